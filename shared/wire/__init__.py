"""Wire protocol between console and telerobot: messages, unit framing, telemetry layout.

``messages`` defines every JSON message once (and explains the exactly-once reasoning),
``units`` frames command units, ``session`` holds the two ends of the command channel as sans-I/O
state machines, ``telemetry`` is the fixed binary frame of the data channel.
"""
