"""rf_gateway."""
