"""The delayed link as a process of its own (``teleprog link``): the WebSocket relay in
``server.relay.link_relay``. It imports nothing from the console; the console reaches it only
over its WebSockets, as it would reach a robot."""
