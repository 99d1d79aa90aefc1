"""Publish/subscribe with a bounded drop-oldest queue per subscriber (docs/architecture.md)."""
