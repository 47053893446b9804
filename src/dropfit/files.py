"""Reading inputs, writing outputs whole or not at all, and the failure records that let a batch carry on.

A stage that meets a bad recording inside a workflow writes a *failure record* in place of each of
its outputs (a NetCDF or JSON file with ``status = "failed"``, a CSV whose only line is a comment,
an HTML page or PNG that shows the message). The next stage finds the record, writes its own, and the
batch summary lists the recording with the original one-line message.
"""

from __future__ import annotations

import contextlib
import csv
import errno
import hashlib
import json
import os
import re
import stat
import tempfile
import textwrap
import zipfile
import zlib
from pathlib import Path

from .errors import InputError, OutputError, one_line, shown, shown_path

FAILED = "failed"
_UMASK = os.umask(0)
os.umask(_UMASK)
_CSV_FAILURE_PREFIX = "# dropfit failed: "
#: A sample id, which names its folder ``<results>/<sample_id>/``: a plain name (letters, digits, ``_ . -``, the
#: first a letter or digit), so that the folder lies inside the results and holds no folder of its own; not
#: ``batch`` or ``logs``, the workflow's own folders there. The same pattern as the workflow's schema
#: (workflow/schemas/samples.schema.yaml), which refuses such an id before any job.
SAMPLE_ID_PATTERN = r"^(?!batch$|logs$)[A-Za-z0-9][A-Za-z0-9_.-]*$"
SAMPLE_ID_ADVICE = "give it a plain name of letters, digits, _ . and - that starts with a letter or digit"


def sample_id_problem(sample_id, results_dir="results"):
    """Why ``sample_id`` cannot name a folder inside ``results_dir`` (:data:`SAMPLE_ID_PATTERN`): words to follow
    ``sample_id '<id>'`` in a message, or None for a good id."""
    if not isinstance(sample_id, str) or not sample_id.strip():
        return "is empty"
    if re.fullmatch(SAMPLE_ID_PATTERN, sample_id):
        return None
    if sample_id in ("batch", "logs"):
        return f"is the name of the workflow's own folder {shown_path(os.path.join(results_dir, sample_id))}"
    if os.path.isabs(sample_id) or any(
            part == ".." for part in re.split(r"[/\\]", sample_id)):
        return f"would put its files outside {shown_path(results_dir)}"
    if re.search(r"[/\\]", sample_id):
        return "is a path of folders, not a plain name"
    return "is not a plain name"


#: The start of the name of the temporary folder inside its ``--out`` in which ``dropfit run`` makes its files
#: (:func:`dropfit.stages.run`); a message names a file there by the name it is moved to.
RUN_TEMPORARY_PREFIX = ".dropfit-run."
#: errno values of an operating-system error that is the user's environment (permissions, a read-only or full
#: disk, a file where a folder belongs, a folder where a file belongs, a name too long), not a bug of dropfit.
ENVIRONMENT_ERRNOS = frozenset(getattr(errno, name) for name in (
    "EACCES", "EPERM", "EROFS", "ENOSPC", "EDQUOT", "ENOTDIR", "EISDIR", "EEXIST", "ENAMETOOLONG", "EFBIG", "EMLINK")
    if hasattr(errno, name))
#: What to do, by errno, for an output that cannot be written.
_WRITE_ADVICE = {
    errno.EACCES: "write into a folder you may write to, or change its permissions",
    errno.EPERM: "write into a folder you may write to, or change its permissions",
    errno.EROFS: "the disk is read-only: write to a folder on a writable disk",
    errno.ENOSPC: "the disk is full: free space on it, or write to another disk",
    getattr(errno, "EDQUOT", errno.ENOSPC): "your disk quota is used up: free space in it, or write elsewhere",
    errno.EFBIG: "the file is larger than that disk takes: write to another disk",
    errno.ENAMETOOLONG: "give a shorter path",
}


def _final_path(path):
    """``path`` as the user knows it: a file in ``dropfit run``'s temporary folder named as the file it becomes."""
    path = Path(path)
    parts = [part for part in path.parts if not part.startswith(RUN_TEMPORARY_PREFIX)]
    return Path(*parts) if parts else path


def _file_in_the_way(path, folder):
    """The nearest of ``path`` (when it is to be a ``folder``) and its parents that exists and is not a folder."""
    for candidate in ([path] if folder else []) + list(path.parents):
        if os.path.lexists(candidate):
            return None if candidate.is_dir() else candidate
    return None


def unwritable(path, error, folder=False):
    """The one-line message for an output ``path`` (a file; a ``folder`` of outputs) that cannot be written,
    ``error`` the :class:`OSError`: the path, what the system said and what to do."""
    path = _final_path(path)
    if error.errno in (errno.ENOTDIR, errno.EEXIST, errno.ENOENT):
        blocker = _file_in_the_way(path, folder)
        if blocker is not None:
            what = f" (for {shown_path(path)})" if blocker != path else ""
            return (f"{shown_path(blocker)}: is a file where a folder is needed{what}; give another folder, or move "
                    f"the file away")
    if error.errno == errno.EISDIR:
        return (f"{shown_path(path)}: is a folder where a file is to be written; give a file name, or move the "
                f"folder away")
    reason = (error.strerror or str(error) or type(error).__name__).lower()
    advice = _WRITE_ADVICE.get(error.errno, "check the folder and the disk it is on")
    return f"{shown_path(path)}: cannot be written ({shown(reason)}); {advice}"


def environment_message(error, path):
    """The one-line message of an :class:`OSError` that is the user's environment (:data:`ENVIRONMENT_ERRNOS`),
    met where no writer named its file: ``path`` where the error names none; None for any other error."""
    if not isinstance(error, OSError) or error.errno not in ENVIRONMENT_ERRNOS:
        return None
    if error.errno in (errno.EACCES, errno.EPERM):
        name = shown_path(_final_path(error.filename or path))
        return f"{name}: permission denied; check that you may read it and write into its folder"
    return unwritable(error.filename or path, error)


@contextlib.contextmanager
def writing(path, folder=False):
    """Within the block, an :class:`OSError` (a refused, read-only or full disk, a file in the way) is an
    :class:`dropfit.errors.OutputError` naming the output ``path`` (a file, or a ``folder`` of outputs):
    :func:`unwritable`."""
    try:
        yield
    except OSError as error:
        if error.errno is None:
            raise
        raise OutputError(one_line(unwritable(path, error, folder))) from None


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path beside ``path``; rename it to ``path`` only if the block succeeds. An output that
    cannot be written (its disk, its folder) is an :class:`dropfit.errors.OutputError` naming it (:func:`writing`)."""
    path = Path(path)
    with writing(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
        os.close(fd)
    try:
        try:
            os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes the file private; outputs get the usual permissions
        except OSError:  # a disk without permissions (FAT, some shares): the file is written all the same
            pass
        with writing(path):
            yield Path(tmp)
            os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            try:
                os.remove(tmp)
            except OSError:
                pass


def write_text(path, text):
    """Write ``text`` to ``path`` atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_json(path, data):
    """Write ``data`` as indented JSON to ``path`` atomically (NaN written as null)."""
    write_text(path, json.dumps(json_ready(data), indent=2, allow_nan=False) + "\n")


def json_ready(value):
    """``value`` with every NaN replaced by None (JSON has no NaN), tuples as lists, nested in dicts and lists."""
    if isinstance(value, float) and value != value:
        return None
    if isinstance(value, dict):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    return value


def write_table(path, table):
    """Write a pandas table as CSV to ``path`` atomically, every number as the shortest text that reads back
    to the same float (so a stage that reads the table gets the very numbers the writer had)."""
    with atomic_output(path) as tmp:
        table.to_csv(tmp, index=False)


def check_input_file(path, what="file"):
    """Raise :class:`InputError` unless ``path`` is a regular file this process can read; return it as a Path.

    ``what`` names the expected file in the advice (e.g. ``"height log or video"``).
    """
    path = Path(path)
    try:
        info = path.stat()
    except FileNotFoundError:
        raise InputError(f"{shown_path(path)}: file not found; check the path") from None
    except OSError as error:
        raise InputError(unreadable(path, error)) from None
    if stat.S_ISDIR(info.st_mode):
        raise InputError(f"{shown_path(path)}: is a directory, not a file; give the {what} inside it")
    if not stat.S_ISREG(info.st_mode):
        raise InputError(f"{shown_path(path)}: is not a regular file (a device, pipe or socket); give the {what}")
    try:
        with open(path, "rb") as handle:
            handle.read(1)
    except OSError as error:
        raise InputError(unreadable(path, error)) from None
    return path


def unreadable(path, error):
    """The message for a file that exists but cannot be read (``error``: the :class:`OSError`)."""
    reason = (error.strerror or type(error).__name__).lower()
    advice = "check that you may read it (its permissions)" if isinstance(error, PermissionError) \
        else "check the file and the disk it is on"
    return f"{shown_path(path)}: cannot be read ({reason}); {advice}"


def read_bytes(path, what="file"):
    """The bytes of the input file ``path``, with :class:`InputError` for a missing or unreadable one."""
    path = check_input_file(path, what)
    try:
        return path.read_bytes()
    except OSError as error:
        raise InputError(unreadable(path, error)) from None


#: The most bytes dropfit reads from a text input (a height log, a tracking table, a sensor export, a Tracker
#: project): 32 MiB, a second's log at 1 MHz (10⁶ rows, 18-19 MB) and room for wider rows. Checked from the
#: file's size before it is read (a 1 GB ``.trk`` of spaces took 2.18 GB).
MAX_TABLE_BYTES = 32 * 1024 * 1024
#: The most lines dropfit reads from a text input: a table costs memory by its rows (`dropfit run` of a log of
#: 10⁶ rows peaked at 575 MB, of 10⁶ rows over seven flights at 850 MB, and of 1.2 × 10⁶ rows at 1055 MB), so
#: 10⁶ data rows, a header and comments keep the largest table accepted under the 1000 MB a job has
#: (benchmarks/reader_peaks.py).
MAX_TABLE_LINES = 1_000_100


def read_table_bytes(path, what, check_head=None):
    """The bytes of the text input ``path`` (a table, a log or a project, named by ``what``), as :func:`read_bytes`,
    with :class:`InputError` for one of more than :data:`MAX_TABLE_BYTES` or :data:`MAX_TABLE_LINES`.
    ``check_head(path, head)``, given, may refuse a file too large by what its first 64 KiB show it is (a video
    or a spreadsheet misnamed), the truer cause."""
    path = check_input_file(path, what)
    advice = ("keep every second row (the flights need far fewer samples) or cut the file into parts of "
              "fewer drops")
    size = path.stat().st_size
    if size > MAX_TABLE_BYTES:
        if check_head is not None:
            with open(path, "rb") as handle:
                check_head(path, handle.read(65536))
        raise InputError(f"{shown_path(path)}: holds {_mib(size)}, more than the {_mib(MAX_TABLE_BYTES)} dropfit reads "
                         f"from a table, log or project (MAX_TABLE_BYTES); {advice}")
    raw = read_bytes(path, what)
    lines = max(raw.count(b"\n"), raw.count(b"\r")) + (not raw.endswith((b"\n", b"\r")))
    if lines > MAX_TABLE_LINES:
        raise InputError(f"{shown_path(path)}: has {lines:,} lines, more than the {MAX_TABLE_LINES:,} dropfit reads "
                         f"from a table, log or project (MAX_TABLE_LINES); {advice}")
    return raw


#: The most bytes a member of a zip archive (a phyphox export's data set, a ``.trz``'s ``.trk``) may unpack to:
#: 16 MiB. A phyphox set of a minute's drops at its fastest rate (500 Hz, five columns) is under 3 MB, a
#: Tracker project of thousands of marked frames a few MB; a table's text costs many times its bytes in
#: memory (`dropfit run` of a 32 MB set took 1.14 GB, of a 16 MiB one 686 MB), so 16 MiB
#: keeps the largest member accepted under the 1000 MB a job has. A zip may claim any size (a bomb lies):
#: a member is read no further than this bound plus one byte.
MAX_ARCHIVE_MEMBER_BYTES = 16 * 1024 * 1024


#: What :mod:`zipfile` raises for a damaged or foreign archive: a bad header, a member name flagged UTF-8 that is
#: not (ValueError), a zip version or compression it does not read (NotImplementedError), cut deflate data.
ZIP_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, OSError, EOFError, ValueError, NotImplementedError)


def _mib(size):
    mib = size / 1024 ** 2
    return f"{mib:.0f} MiB" if mib >= 10 else f"{mib:.3g} MiB" if mib >= 1 else f"{size} bytes"


def read_archive_member(path, archive, name, advice, bound=MAX_ARCHIVE_MEMBER_BYTES):
    """The bytes of member ``name`` of the open :class:`zipfile.ZipFile` ``archive`` (the file ``path``), read
    no further than ``bound`` (:data:`MAX_ARCHIVE_MEMBER_BYTES`, or what is left of it for several members);
    :class:`InputError` naming the bound for a larger one (by the size it declares, or, when that lies, by
    what it unpacks to), ending with ``advice`` (what to do)."""
    declared = archive.getinfo(name).file_size

    def refuse(size):
        limit = f"the {_mib(MAX_ARCHIVE_MEMBER_BYTES)} dropfit reads from an archive (MAX_ARCHIVE_MEMBER_BYTES"
        if bound < MAX_ARCHIVE_MEMBER_BYTES:  # the members before it took the rest
            return InputError(f"{shown_path(path)}: its members up to '{shown(name, 60)}' unpack to more than "
                              f"{limit}, all members together); {advice}")
        return InputError(f"{shown_path(path)}: its member '{shown(name, 60)}' unpacks to {size}, more than "
                          f"{limit}); {advice}")

    if declared > bound:
        raise refuse(_mib(declared))
    try:
        with archive.open(name) as member:
            raw = member.read(bound + 1)
    except (*ZIP_ERRORS, RuntimeError) as error:  # (RuntimeError: an encrypted member)
        # a damaged member (bad CRC, deflate data cut), or one compressed or encrypted as zipfile cannot read
        raise InputError(f"{shown_path(path)}: its member '{shown(name, 60)}' cannot be unpacked (a damaged zip: "
                         f"{shown(error)}); save or export it again, unencrypted") from None
    if len(raw) > bound:
        raise refuse(f"more than it declares ({_mib(declared)})")
    return raw


def decoded_text(raw):
    """The text of a file's bytes and its encoding: UTF-8 (a byte-order mark dropped), else Windows-1252, the
    encoding a Windows spreadsheet saves "CSV" in (``Höhe`` as the byte 0xF6); bytes it leaves undefined
    become U+FFFD.

    Returns
    -------
    (str, str)
        The text and ``"utf-8"`` or ``"cp1252"``.
    """
    try:
        return raw.decode("utf-8").removeprefix("\ufeff"), "utf-8"
    except UnicodeDecodeError:
        return raw.decode("cp1252", errors="replace"), "cp1252"


def read_json(path, what="JSON file written by a dropfit stage"):
    """Read a JSON file written by a dropfit stage; raise :class:`InputError` for a failure record
    (with the record's message) and for a file that is missing, unreadable or not JSON."""
    raw = read_bytes(path, what)
    name = shown_path(path)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{name}: is not a JSON text file (binary data); give the {what}") from None
    try:
        data = json.loads(text)
    except ValueError as error:
        if not text.strip():
            raise InputError(f"{name}: is empty; run the stage that writes it again") from None
        cut = not text.rstrip().endswith(("}", "]"))  # dropfit's JSON files end with their closing bracket
        raise InputError(f"{name}: is not valid JSON ({shown(getattr(error, 'msg', error))} at line "
                         f"{getattr(error, 'lineno', '?')}): the file is {'truncated' if cut else 'damaged'}; "
                         f"run the stage that writes it again") from None
    if isinstance(data, dict) and data.get("status") == FAILED:
        raise InputError(one_line(data.get("error") or f"{name}: a failure record without its message"))
    return data


def sha256_of(path):
    """Hex SHA-256 of the file at ``path``."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_failure(path, message, figure_png=None):
    """Write a failure record carrying ``message`` to ``path``; its suffix decides the format. An HTML
    record shows ``figure_png`` (PNG bytes: a refused video's contact sheet) under the message."""
    path = Path(path)
    message = one_line(message)
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
        from .report import failure_page_html

        write_text(path, failure_page_html(message, figure_png))
    elif suffix == ".png":
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        # the message quotes the user's text (cells, paths): drawn literally, never as mathtext ($…$), and
        # wrapped here (matplotlib's own wrapping measures the lines as mathtext even so)
        fig = plt.figure(figsize=(6, 1.2))
        fig.text(0.02, 0.5, "Analysis failed:\n" + textwrap.fill(message, 90), va="center", fontsize=8,
                 parse_math=False)
        with atomic_output(path) as tmp:
            fig.savefig(tmp, format="png")
        plt.close(fig)
    else:
        write_text(path, f"dropfit failed: {message}\n")


def csv_failure_message(path):
    """The message of a CSV failure record at ``path``, or None if it is an ordinary CSV."""
    with open(path, "rb") as handle:
        first = handle.readline(1 << 16).decode("utf-8", errors="replace")
    if first.startswith(_CSV_FAILURE_PREFIX):
        return first[len(_CSV_FAILURE_PREFIX):].strip()
    return None


def read_table(path, what="CSV table written by dropfit analyse"):
    """Read a CSV table written by a dropfit stage; raise :class:`InputError` for a failure record (with
    its message) and for a file that is missing, unreadable, binary, truncated or has ragged rows."""
    import io

    import pandas as pd

    raw = read_bytes(path, what)
    name = shown_path(path)
    if raw.startswith(_CSV_FAILURE_PREFIX.encode()):
        raise InputError(one_line(raw.split(b"\n", 1)[0][len(_CSV_FAILURE_PREFIX):].decode("utf-8", "replace").strip()))
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{name}: is not a text CSV (binary data); give the {what}") from None
    if "\x00" in text:
        raise InputError(f"{name}: is not a text CSV (it holds NUL bytes); give the {what}")
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    if not lines:
        raise InputError(f"{name}: is empty (no header and no rows); run the stage that writes it again")
    if lines[0].lstrip().startswith(("{", "[")):
        raise InputError(f"{name}: is a JSON file, not a CSV table; give the {what}")
    if not text.endswith(("\n", "\r")):  # dropfit ends every table with a line break
        raise InputError(f"{name}: is truncated (its last line is cut short); run the stage that writes it again")
    # fields as the csv module splits them: a quoted note may hold commas
    rows = csv.reader(lines)
    width = len(next(rows))
    for number, fields in enumerate(rows, start=1):
        if len(fields) != width:
            raise InputError(f"{name}: row {number} has {len(fields)} fields but the header has {width}: the "
                             f"file is damaged; run the stage that writes it again")
    # pandas ≥ 3 reads floats back exactly by default; older ones need the round-trip parser
    exact = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
    try:
        return pd.read_csv(io.StringIO("\n".join(lines)), **exact)
    except (ValueError, pd.errors.ParserError) as error:
        raise InputError(f"{name}: is not a valid CSV table ({shown(str(error).splitlines()[0])}); "
                         f"run the stage that writes it again") from None
