"""One error type for every bad input, so that the CLI and the workflow print one clear line.

Every message names the file (when there is one), the field, row or column, and what was expected.
"""

from __future__ import annotations

#: longest message (characters) an InputError prints; a longer one is cut, saying how much was left out
MAX_MESSAGE = 800


def short_repr(value, limit: int = 80) -> str:
    """``repr(value)`` cut to about ``limit`` characters (for 'got ...' in messages: bounded length)."""
    import reprlib

    r = reprlib.Repr()
    r.maxstring = r.maxother = limit
    r.maxlist = r.maxdict = r.maxtuple = r.maxset = 8
    r.maxlevel = 3
    text = r.repr(value)
    return text if len(text) <= limit + 20 else text[:limit] + "..."


class InputError(ValueError):
    """Bad user input: a robot file, a config, a CSV or a command-line value.

    ``str(err)`` is the complete message (one line, at most :data:`MAX_MESSAGE` characters), e.g.
    ``config/robots/x.yaml: field 'links_m[1]': expected a number > 0, got -0.4``. ``message`` is the part
    after the source and field.
    """

    def __init__(self, message: str, *, source: str | None = None, field: str | None = None):
        message = " ".join(str(message).split())  # one line
        if len(message) > MAX_MESSAGE:
            message = message[:MAX_MESSAGE] + f"... ({len(message) - MAX_MESSAGE} characters cut)"
        self.message, self.source, self.field = message, source, field
        parts = []
        if source:
            parts.append(f"{source}:")
        if field:
            parts.append(f"field '{field}':")
        parts.append(message)
        super().__init__(" ".join(parts))

    def renamed(self, field: str | None = None, source: str | None = None) -> "InputError":
        """The same error with another field name or source (e.g. an API argument named as a CLI option)."""
        return InputError(self.message, source=source if source is not None else self.source,
                          field=field if field is not None else self.field)
