"""Built-in protocols, one module each; the module name (with - for _) is the CLI id."""
