"""The live site: robots (one localizer each), their sources, the LED coordinator."""
