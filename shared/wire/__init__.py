"""Wire protocol between console and telerobot: messages, unit framing, telemetry layout."""
