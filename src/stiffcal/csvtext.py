"""CSV text of numeric columns without pandas: the map jobs write tables of 10^5 rows and more and need
nothing else of pandas (importing it costs a job about 0.3 s of CPU). The bytes are what
``pandas.DataFrame.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\\n")`` writes
(:func:`stiffcal.paper.tables.write_csv`; tested against pandas)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: the float format of every table the workflow writes
FLOAT_FORMAT = "%.10g"


def numeric_csv(columns: dict[str, np.ndarray]) -> str | None:
    """The CSV text of equally long 1-D float64 or int64 columns (name -> (N,)), one %-format per column (NaN as
    an empty field, as pandas writes it); None when a column has another type or a name needs quoting."""
    names = list(columns)
    if not names or any(set(c) & set(',"\n\r') for c in names):
        return None
    cols = []
    for a in columns.values():
        a = np.asarray(a)
        if a.dtype == np.float64:
            s = ((FLOAT_FORMAT + "\n") * len(a) % tuple(a.tolist())).split("\n")[:-1]
            for i in np.flatnonzero(np.isnan(a)).tolist():
                s[i] = ""
        elif a.dtype == np.int64:
            s = ("%d\n" * len(a) % tuple(a.tolist())).split("\n")[:-1]
        else:
            return None
        cols.append(s)
    return ",".join(names) + "\n" + "".join(",".join(r) + "\n" for r in zip(*cols))


def write_numeric_csv(columns: dict[str, np.ndarray], path: str | Path) -> None:
    """Write :func:`numeric_csv` atomically (a temporary file moved into place when complete)."""
    from .integrity import atomic_path

    text = numeric_csv(columns)
    if text is None:
        raise ValueError("write_numeric_csv: every column must be float64 or int64, every name plain")
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
