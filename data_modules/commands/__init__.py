"""Tool subcommands of the ``radar2shape`` console script that live in data_modules."""
