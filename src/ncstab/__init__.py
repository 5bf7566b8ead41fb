"""ncstab: stability analysis of non-conservative discrete systems."""

__version__ = "0.1.0"
