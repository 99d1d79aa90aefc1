"""localizer."""
