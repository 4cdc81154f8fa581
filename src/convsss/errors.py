"""The one exception type users see.

Every check on user input raises :class:`ConvsssError` with a one-line message that names the bad value and what
is allowed. The command line turns it into ``error: <message>`` and exit code 2, with no traceback.
"""


class ConvsssError(ValueError):
    """Bad input or an unusable environment, explained in one line."""
