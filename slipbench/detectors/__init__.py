"""Built-in detectors, one module each; the module name (with - for _) is the CLI id."""
