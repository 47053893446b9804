"""The one exception type for problems with a user's input."""


class InputError(Exception):
    """A recording or configuration that cannot be analysed.

    The message is one line that names the file, says what is wrong and, where it helps, what to
    do. The command line prints it without a traceback.
    """
