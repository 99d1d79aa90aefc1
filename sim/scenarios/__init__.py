"""Built-in scenario files (YAML), loaded by `sim.scenario.load_scenario`."""
