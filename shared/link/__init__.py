"""The delayed link's core: sans-I/O, explicit timestamps in, deliveries out (``core.LinkCore``)."""
