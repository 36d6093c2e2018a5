"""Analyses and headlines for chaos scenes (see clockwork.analyses)."""
