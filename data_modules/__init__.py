"""LightningDataModules, Datasets and dataset builders that read/write radar2shape records."""
