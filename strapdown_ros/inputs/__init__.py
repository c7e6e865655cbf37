"""Readers of external data a scenario points to (sample files, bags), outside the core."""
