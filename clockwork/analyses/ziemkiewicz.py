"""Analyses and headlines for ziemkiewicz scenes (see clockwork.analyses)."""
