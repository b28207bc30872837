"""Tool subcommands of the ``radar2shape`` console script.

Each module here defines ``configure_parser(parser)`` and ``main(args) -> int``;
``radar2shape.cli`` finds them by name, so adding a command never edits the CLI.
"""
