"""Error type for refused SWT datasets."""


class LogFormatError(ValueError):
    """An SWT log, summary or its metadata was refused.

    The message is one line and names the problem: file line, column, unit or metadata key.
    """
