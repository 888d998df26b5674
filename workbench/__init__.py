"""Decoration workbench: pre-distorted prints for decorated plastic parts, and their validation."""

__version__ = "0.1.0"
