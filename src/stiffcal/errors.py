"""One error type for every bad input, so that the CLI and the workflow print one clear line.

Every message names the file (when there is one), the field, row or column, and what was expected.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad user input: a robot file, a config, a CSV or a command-line value.

    ``str(err)`` is the complete message, e.g.
    ``config/robots/x.yaml: field 'links_m[1]': expected a number > 0, got -0.4``.
    """

    def __init__(self, message: str, *, source: str | None = None, field: str | None = None):
        self.source = source
        self.field = field
        parts = []
        if source:
            parts.append(f"{source}:")
        if field:
            parts.append(f"field '{field}':")
        parts.append(message)
        super().__init__(" ".join(parts))
