"""The commands, a module each named as the command: tactile-viewer, -record, -sim and -tradeoff."""
