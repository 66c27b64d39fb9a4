"""The virtual clock and the in-memory network: the event loop on simulated time (vclock, its timer queue vqueue)
and the fabric that carries the datagrams between the masters and the card cores (fabric).

May import the slave layer's state files (the cards' EEPROM images) and :mod:`mlink_sim.impair`; not the master
or run layers.
"""
