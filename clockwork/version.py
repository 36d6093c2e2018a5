"""The package's version, on the ground floor: every layer may name it, and
the package's face (``clockwork/__init__.py``) stays on top of the house."""

__version__ = "0.1.0"
