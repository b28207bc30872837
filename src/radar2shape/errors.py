"""Errors that reach the user as one clear line instead of a deep traceback."""


class UserInputError(ValueError):
    """Bad input from a user: the message names the file/field and what was expected."""
