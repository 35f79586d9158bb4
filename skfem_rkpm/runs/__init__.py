"""Scene files to results: the only folder that knows TOML, run folders and figures."""
