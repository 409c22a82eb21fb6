"""The error the pure format code raises on input that breaks a format (a serial line format
description, a table a controller cannot take). The command line turns it into exit status 2 and
one `error:` line, like campaign.errors.InputError."""


def one_line(text: str) -> str:
    """`text` with line breaks and other control characters escaped, so it prints as one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


class FormatError(ValueError):
    """Input that does not fit a format. The message says what is wrong and where; it is one line
    (control characters from the input are escaped)."""

    def __init__(self, message: str = ""):
        super().__init__(one_line(message))
