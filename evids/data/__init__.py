"""Dataset loaders: generated data and public benchmark formats."""
