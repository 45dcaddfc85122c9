"""Shared by the experiment scripts: write a list of result rows (dicts) as a CSV file."""
from __future__ import annotations

import csv
import os


def write_rows(path, rows, keys=None):
    """Write ``rows`` to ``path`` (folders made as needed). The columns are ``keys``, or every
    key of the rows in the order first seen; a row without a column leaves it empty."""
    if keys is None:
        keys = list(dict.fromkeys(k for r in rows for k in r))
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, restval="")
        w.writeheader()
        w.writerows(rows)
