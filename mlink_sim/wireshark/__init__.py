"""The Wireshark dissector shipped with mlink-sim (``mlink.lua``) and where it goes (``mlink-sim wireshark``)."""
