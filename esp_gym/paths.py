"""Whether an output path can be written, found before any work: one probe for every command line
(``esp-gym``'s ``--out``, the agents' ``--out``, ``--runs`` and ``--models``).
Light on purpose (the standard library only): the command lines' parsers use it.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Optional


def cannot_write(path) -> Optional[str]:
    """Why a directory ``path`` could not be made (with its missing parents) and written in, or
    None if it can. A probe file is created and removed in the nearest directory that exists:
    nothing is left behind, and what the file system itself refuses is found (os.access lets root
    pass on a read-only or virtual file system, where writing then fails)."""
    base = Path(path).absolute()
    try:
        while not base.exists():
            base = base.parent
    except OSError as err:  # a parent that cannot be looked at
        return f"cannot look at {base} ({err.strerror or err})"
    if not base.is_dir():
        return f"{base} is not a directory"
    try:
        with tempfile.NamedTemporaryFile(dir=base, prefix=".write-probe-"):
            pass
    except OSError as err:
        return f"cannot write in {base} ({err.strerror or err})"
    return None
