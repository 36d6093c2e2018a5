"""Analyses and headlines for hoyng scenes (see clockwork.analyses)."""
