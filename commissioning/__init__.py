"""Commissioning logic (docs/commissioning.md)."""
