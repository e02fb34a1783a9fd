"""Session recording and replay: every console session as one MCAP file (Foxglove opens it; the
console's replay scrubs it). ``records`` names the topics and their payloads, ``writer`` writes
them on a thread of its own, ``recorder`` turns the session's events into records, ``reader``
reads a file back (up to the last complete chunk of a cut-off one)."""
