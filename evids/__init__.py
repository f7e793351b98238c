"""evids."""
