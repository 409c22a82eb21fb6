"""Errors that end a command with exit status 2 and one line on stderr starting with `error:`."""


class InputError(Exception):
    """Bad input: a file, a config, a serial line or a command-line value.

    The message says what is wrong and where (file, line, column or key). The CLI prints it as
    `error: <message>` and exits with status 2.
    """


class SafetyError(InputError):
    """A motion would leave the soft limits or exceed the velocity limit. Nothing was commanded."""
