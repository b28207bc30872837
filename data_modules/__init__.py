"""LightningDataModules, Datasets and dataset builders that read/write radar2shape records.

The DataModules are imported lazily, so the builder and its worker processes do not pay for
importing Lightning.
"""

__all__ = ["ProfileDataModule", "ShapeDataModule"]


def __getattr__(name: str):
    if name in __all__:
        from data_modules import datamodules

        return getattr(datamodules, name)
    raise AttributeError(f"module 'data_modules' has no attribute {name!r}")
