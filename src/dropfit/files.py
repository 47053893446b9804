"""Writing outputs whole or not at all, and the failure records that let a batch carry on.

A stage that meets a bad recording inside a workflow writes a *failure record* in place of each of
its outputs (a NetCDF or JSON file with ``status = "failed"``, a CSV whose only line is a comment,
an HTML page or PNG that shows the message). The next stage finds the record, writes its own, and the
batch summary lists the recording with the original one-line message.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from pathlib import Path

from .errors import InputError

FAILED = "failed"
_UMASK = os.umask(0)
os.umask(_UMASK)
_CSV_FAILURE_PREFIX = "# dropfit failed: "


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path beside ``path``; rename it to ``path`` only if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes the file private; outputs get the usual permissions
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def write_text(path, text):
    """Write ``text`` to ``path`` atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_json(path, data):
    """Write ``data`` as indented JSON to ``path`` atomically (NaN written as null)."""
    write_text(path, json.dumps(_nan_to_none(data), indent=2, allow_nan=False) + "\n")


def _nan_to_none(value):
    if isinstance(value, float) and value != value:
        return None
    if isinstance(value, dict):
        return {key: _nan_to_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_nan_to_none(item) for item in value]
    return value


def read_json(path):
    """Read a JSON file written by a dropfit stage; raise :class:`InputError` for a failure record."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise InputError(f"{path}: cannot read this JSON file ({type(error).__name__}: {error})") from None
    if isinstance(data, dict) and data.get("status") == FAILED:
        raise InputError(data["error"])
    return data


def sha256_of(path):
    """Hex SHA-256 of the file at ``path``."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_failure(path, message):
    """Write a failure record carrying ``message`` to ``path``; its suffix decides the format."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".json":
        write_json(path, {"status": FAILED, "error": message})
    elif suffix == ".csv":
        write_text(path, f"{_CSV_FAILURE_PREFIX}{message}\n")
    elif suffix == ".nc":
        import xarray as xr

        with atomic_output(path) as tmp:
            xr.Dataset(attrs={"status": FAILED, "error": message}).to_netcdf(tmp)
    elif suffix in (".html", ".htm"):
        from html import escape

        write_text(
            path,
            "<!doctype html><meta charset='utf-8'><title>dropfit: failed</title>"
            f"<h1>Analysis failed</h1><p>{escape(message)}</p>\n",
        )
    elif suffix == ".png":
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=(6, 1.2))
        fig.text(0.02, 0.5, "Analysis failed:\n" + message, va="center", fontsize=8, wrap=True)
        with atomic_output(path) as tmp:
            fig.savefig(tmp, format="png")
        plt.close(fig)
    else:
        write_text(path, f"dropfit failed: {message}\n")


def csv_failure_message(path):
    """The message of a CSV failure record at ``path``, or None if it is an ordinary CSV."""
    with open(path, encoding="utf-8") as handle:
        first = handle.readline()
    if first.startswith(_CSV_FAILURE_PREFIX):
        return first[len(_CSV_FAILURE_PREFIX):].strip()
    return None


def read_table(path):
    """Read a CSV table written by a dropfit stage; raise :class:`InputError` for a failure record."""
    import pandas as pd

    try:
        message = csv_failure_message(path)
        table = pd.read_csv(path, comment="#") if message is None else None
    except (OSError, ValueError) as error:
        raise InputError(f"{path}: cannot read this table ({type(error).__name__})") from None
    if message is not None:
        raise InputError(message)
    return table
