"""Design exploration: sweep specifications, batched runs, metrics, results as NetCDF."""
