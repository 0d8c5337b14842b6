"""Arrival sequencing: the one place where landing order and times are decided."""
