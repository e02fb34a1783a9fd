"""Session recording and replay: every console session as one MCAP file."""
