"""Programs as the operator builds them: the editor state machine and automatic generation."""
