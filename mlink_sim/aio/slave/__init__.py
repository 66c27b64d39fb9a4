"""The slave side over UDP: the slave server of one process (server), the stations sharing a port as on a bus
(bus), the card cores built from the configuration (stations), their EEPROM image files (state), the drive
faults planted on them (faults), the sources that may change a station (allow) and the control endpoints' token
(token).

May import the transport and timing layers and the cores (cards, drive, faults, metrics); not the master, virtual
or run layers.
"""
