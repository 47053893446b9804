"""Property-based fuzzing of the table, project and archive readers (issue 33, item 6).

Each reader is fed malformed input: random bytes, small valid files of each format mutated (characters and
lines inserted, deleted or replaced, separators swapped, fields emptied, huge numbers, NaN and inf, bytes that
are not UTF-8), and zips with random members (a ``.trk`` of mutated XML among them). Whatever it is fed, a
reader either reads it or raises :class:`dropfit.errors.InputError` with one line; any other exception is a
bug. Hypothesis is derandomized (the project seeds every random generator: CI sees the same examples on
every run) and keeps no example database; ``max_examples`` bounds the time (the file runs in about half a
minute on a loaded 2-core machine).
"""

import io
import itertools
import os
import warnings
import zipfile

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from dropfit.audio.tables import read_impact_table
from dropfit.errors import LINE_LIMIT, InputError
from dropfit.heightlog import read_height_log
from dropfit.importers import FORMATS, ImportOptions, read_track

#: Examples per test (small files: a few ms each), the file well under a minute on a loaded machine;
#: ``DROPFIT_FUZZ_EXAMPLES=5000 pytest tests/test_fuzz.py`` searches deeper, as derandomized.
EXAMPLES = int(os.environ.get("DROPFIT_FUZZ_EXAMPLES", "200"))
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

_rows = [(0.01 * i, 1.0 - 4.9 * (0.01 * i) ** 2) for i in range(12)]

#: A small valid file of each text format, and its suffix.
SEEDS = {
    "dropfit": (".csv", "# height log\ntime_s,y_m,x_m\n" + "".join(f"{t:.2f},{y:.4f},0.1\n" for t, y in _rows)),
    "csv": (".csv", "Zeit (s);Höhe (cm)\n" + "".join(f"{t:.2f};{100 * y:.2f}\n".replace(".", ",")
                                                       for t, y in _rows)),
    "tracker": (".txt", "mass A\nt\tx\ty\n" + "".join(f"{t:.2f}\t0.1\t{y:.4f}\n" for t, y in _rows)),
    "tracker2": (".txt", "hand\t\t\tball\t\t\nt\tx\ty\tt\tx\ty\n"
                 + "".join(f"{t:.2f}\t0.3\t0.5\t{t:.2f}\t0.1\t{y:.4f}\n" for t, y in _rows)),
    "mtrack2": (".txt", "Tracks 1 to 2\nFrame\tX1\tY1\tFlag1\tX2\tY2\tFlag2\n"
                + "".join(f"{i + 1}\t12.0\t30.5\t0\t{100 + i}.0\t{400 - 500 * y:.2f}\t*\n" for i, (_, y) in
                          enumerate(_rows)) + "\nTrack \tLength\tDistance traveled\tNr of Frames\n1\t0\t0\t12\n"),
    "mtrack2-spaces": (".txt", "Frame X1 Y1 Flag1\n" + "".join(f"{i + 1} 12.0 {400 - 500 * y:.2f}\n"
                                                               for i, (_, y) in enumerate(_rows))),
    "trackmate": (".csv", "LABEL,ID,TRACK_ID,POSITION_X,POSITION_Y,POSITION_T,FRAME\nLabel,Spot ID,Track ID,X,Y,T,"
                  "Frame\n,,,(pixel),(pixel),(sec),\n"
                  + "".join(f"ID{i},{i},0,100.0,{400 - 500 * y:.2f},{t:.2f},{i}\n" for i, (t, y) in enumerate(_rows))),
    "vernier": (".csv", "Run 1: Time (s),Run 1: Position (m),Run 2: Time (s),Run 2: Position (m)\n"
                + "".join(f"{t:.2f},{1.5 - y:.4f},{t:.2f},{1.4 - y:.4f}\n" for t, y in _rows)),
    "pasco": (".csv", "Time (s) Run #1,Position (m) Run #1\n" + "".join(f"{t:.2f},{1.5 - y:.4f}\n" for t, y in _rows)),
    "phyphox": (".csv", '"Time (s)","Distance (m)"\n' + "".join(f"{t:.4E},{1.5 - y:.6E}\n" for t, y in _rows)),
    "kinovea": (".txt", "Time;X (cm);Y (cm)\n"
                + "".join(f"0:00:00:{i:02d};10,0;{100 * y:.2f}\n".replace(".", ",") for i, (_, y) in enumerate(_rows))),
}
TRK = ('<?xml version="1.0" encoding="UTF-8"?>\n<object class="org.opensourcephysics.cabrillo.tracker.TrackerPanel">'
       '<property name="videoclip" type="object"><object class="org.opensourcephysics.media.core.VideoClip">'
       '<property name="startframe" type="int">3</property><property name="starttime" type="double">100.0</property>'
       '</object></property><property name="clipcontrol" type="object"><object class="org.opensourcephysics.media.'
       'core.StepperClipControl"><property name="delta_t" type="double">20.0</property></object></property>'
       '<property name="coords" type="object"><object class="org.opensourcephysics.media.core.ImageCoordSystem">'
       '<property name="framedata" type="array" class="[Lorg.opensourcephysics.media.core.ImageCoordSystem'
       '$FrameData;"><property name="[0]" type="object"><object class="org.opensourcephysics.media.core.'
       'ImageCoordSystem$FrameData"><property name="xorigin" type="double">100.0</property><property name="yorigin" '
       'type="double">450.0</property><property name="angle" type="double">10.0</property><property name="xscale" '
       'type="double">500.0</property><property name="yscale" type="double">500.0</property></object></property>'
       '</property></object></property><property name="length_unit" type="string">m</property>'
       '<property name="tracks" type="collection" class="java.util.ArrayList"><property name="item" type="object">'
       '<object class="org.opensourcephysics.cabrillo.tracker.PointMass"><property name="name" type="string">ball'
       '</property><property name="framedata" type="array" class="[Lorg.opensourcephysics.cabrillo.tracker.'
       'PointMass$FrameData;">'
       + "".join(f'<property name="[{i + 3}]" type="object"><object class="org.opensourcephysics.cabrillo.tracker.'
                 f'PointMass$FrameData"><property name="x" type="double">{100 + i}.0</property><property name="y" '
                 f'type="double">{450 - 500 * y:.3f}</property></object></property>' for i, (_, y) in enumerate(_rows))
       + '</property></object></property></property></object>\n')
#: Tables of impact times: dropfit's own, phyphox's "(In)elastic collision" and its "Acoustic Stopwatch".
IMPACT_SEEDS = {
    "csv": "impact_time_s,impact_time_se_s\n0.50,0.001\n1.20,0.001\n1.75,0.001\n2.18,0.001\n2.52,0.001\n",
    "phyphox": "Bounce 0 (s);Bounce 1 (s);Bounce 2 (s);Height 0 (m)\n0,5;1,2;1,75;0,6\n",
    "stopwatch": '"Event time (s)","Interval (s)"\n0.50,0.50\n1.20,0.70\n1.75,0.55\n2.18,0.43\n',
}

#: Text that breaks readers: numbers past float's range, non-finite values, quotes, separators, control and
#: non-UTF-8 bytes, a byte-order mark, a unit in brackets, a header name.
TOKENS = [b"", b"nan", b"NaN", b"inf", b"-inf", b"1e309", b"-1e309", b"1e-400", b"9" * 400, b"0x1p3", b"-0",
          b"1,5", b'"', b'""', b",", b";", b"\t", b"|", b" ", b"\n", b"\r", b"\r\n", b"#", b"\x00", b"\xff",
          b"\xfe\xff", b"\xc3", b"\xef\xbb\xbf", b"\x1b[31m", b"(m)", b"[cm]", b"(s)", b"time_s", b"y_px", b"x_m",
          b"Run 1:", b"TRACK_ID", b"POSITION_Y", b"Tracks 1 to 2", b"Frame", b"*", b"<", b"<?xml", b"]]>", b"&amp;",
          b"&#0;", "\u00e9".encode(), "\u202e".encode(), b"1:02:03:04", b"None", b"1" * 20000]
SEPARATOR_BYTES = [b",", b";", b"\t", b"|", b" ", b"", b"\n", b",,"]

#: A Logger Pro table whose one run with a time column (the other's name spoilt) misses a time: its distances
#: were searched for bounces before the times were checked (ValueError).
ONE_RUN_TIME_MISSING = SEEDS["vernier"][1].replace("Run 1: Time", "Run 1:nan Time").replace(
    "\n0.05,0.5122,0.05,", "\n0.05,0.5122,,").encode()

_names = itertools.count()


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """One folder for every example (a function-scoped tmp_path would be shared by Hypothesis' examples)."""
    return tmp_path_factory.mktemp("fuzz")


def _write(folder, suffix, data):
    path = folder / f"f{next(_names)}{suffix}"
    path.write_bytes(data)
    return path


def _check(call):
    """Run ``call``: reading is fine, InputError must be one line; any other exception propagates (a bug)."""
    try:
        call()
    except InputError as error:
        message = str(error)
        assert "\n" not in message and len(message) < LINE_LIMIT, message


@st.composite
def mutated(draw, seed):
    """``seed`` (bytes) with a few edits: characters or tokens inserted, deleted or replaced, lines deleted,
    doubled or swapped, a separator replaced by another everywhere, fields emptied."""
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.sampled_from(["insert", "delete", "replace", "byte", "line", "separator", "empty"]))
        at = draw(st.integers(0, max(len(data), 1) - 1)) if data else 0
        if kind == "insert":
            data[at:at] = draw(st.sampled_from(TOKENS) | st.binary(max_size=8))
        elif kind == "delete":
            del data[at: at + draw(st.integers(1, 40))]
        elif kind == "replace":
            data[at: at + draw(st.integers(1, 8))] = draw(st.sampled_from(TOKENS))
        elif kind == "byte":
            data[at: at + 1] = bytes([draw(st.integers(0, 255))])
        elif kind == "line":
            lines = bytes(data).split(b"\n")
            line = draw(st.integers(0, len(lines) - 1))
            how = draw(st.sampled_from(["delete", "double", "swap", "truncate"]))
            if how == "delete":
                del lines[line]
            elif how == "double":
                lines.insert(line, lines[line])
            elif how == "swap" and len(lines) > 1:
                other = draw(st.integers(0, len(lines) - 1))
                lines[line], lines[other] = lines[other], lines[line]
            else:
                lines[line] = lines[line][: draw(st.integers(0, max(len(lines[line]), 1)))]
            data = bytearray(b"\n".join(lines))
        elif kind == "separator":
            old, new = draw(st.sampled_from(SEPARATOR_BYTES[:5])), draw(st.sampled_from(SEPARATOR_BYTES))
            data = bytearray(bytes(data).replace(old, new))
        else:  # a field emptied: the text between two separators removed
            text = bytes(data)
            start = text.find(b",", at)
            end = text.find(b",", start + 1) if start >= 0 else -1
            if 0 <= start < end:
                data[start + 1: end] = b""
    return bytes(data)


def _zip(members):
    buffer = io.BytesIO()
    with warnings.catch_warnings(), zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as archive:
        warnings.simplefilter("ignore", UserWarning)  # a member name twice ("Duplicate name"): as intended
        for name, content in members:  # (a fixed date: the same bytes on every run)
            archive.writestr(zipfile.ZipInfo(name, date_time=(2024, 5, 2, 12, 0, 0)), content, zipfile.ZIP_DEFLATED)
    return buffer.getvalue()


#: A phyphox export whose data set's deflated bytes were damaged (zlib.error escaped the readers).
DAMAGED_PHYPHOX = _zip([("meta/", b""), ("Distance.csv", SEEDS["phyphox"][1].encode())])
DAMAGED_PHYPHOX = DAMAGED_PHYPHOX[:79] + b"\x00" + DAMAGED_PHYPHOX[80:]
#: A Tracker .trz whose .trk's deflated bytes were damaged.
DAMAGED_TRZ = _zip([("drop.trk", TRK.encode())])
DAMAGED_TRZ = DAMAGED_TRZ[:60] + b"\x00" + DAMAGED_TRZ[61:]
#: A .trz whose central directory asks for a zip version zipfile does not read (NotImplementedError escaped).
VERSION_6_4 = _zip([("drop.trk", TRK.encode())])
VERSION_6_4 = VERSION_6_4[:VERSION_6_4.index(b"PK\x01\x02") + 6] + bytes([64]) + \
    VERSION_6_4[VERSION_6_4.index(b"PK\x01\x02") + 7:]
#: A zip whose member name, flagged UTF-8, is not (UnicodeDecodeError escaped the Tracker reader).
NAME_NOT_UTF8 = _zip([("meta/", b""), ("\x80", b"")])
NAME_NOT_UTF8 = NAME_NOT_UTF8[:168] + b"\x00" + NAME_NOT_UTF8[169:]


_member_names = st.sampled_from(["meta/", "meta/device.csv", "Distance.csv", "Raw data.csv", "Energy.csv",
                                 "drop.trk", "sub/drop.TRK", "../escape.trk", "/abs.csv", "x.csv", "drop.mp4",
                                 "meta/time.csv", "Impact.csv", "Événement.csv", ".csv"]) | \
    st.text(max_size=12).filter(lambda name: name and "\x00" not in name)
_member_content = st.one_of(st.binary(max_size=200), *(mutated(text.encode()) for _, text in SEEDS.values()),
                            mutated(TRK.encode()), *(mutated(text.encode()) for text in IMPACT_SEEDS.values()))
archives = st.lists(st.tuples(_member_names, _member_content), max_size=4).map(_zip)
#: A zip whose bytes were cut or changed after it was written (a damaged download).
damaged_archives = st.tuples(archives, st.integers(0, 400), st.integers(0, 255)).map(
    lambda a: a[0][: a[1]] + bytes([a[2]]) + a[0][a[1] + 1:])

_text_seeds = st.sampled_from(sorted(SEEDS))
text_files = _text_seeds.flatmap(lambda key: st.tuples(
    st.sampled_from([SEEDS[key][0], ".csv", ".txt", ".tsv", ".dat", ""]), mutated(SEEDS[key][1].encode())))
options = st.builds(ImportOptions, format=st.none() | st.sampled_from(sorted(set(FORMATS) - {"mraw"})),
                    fps=st.none() | st.just(30.0), track_id=st.none() | st.sampled_from([0, 1, 2, 7]),
                    columns=st.none() | st.sampled_from(["time=t[s],y=y[m]", "frame=Frame,y=Y2", "time=1,y=2[cm]",
                                                         "y=height", "time=Zeit[s],y=Höhe[cm]"]),
                    sensor_height_m=st.none() | st.just(1.5))


@FUZZ
@given(suffix=st.sampled_from([".csv", ".txt", ".trk", ".trz", ".zip", ".xyz", ""]), data=st.binary(max_size=300),
       opts=options)
@example(suffix=".csv", data=b"\t", opts=ImportOptions(columns="time=t[s],y=y[m]"))  # no line: IndexError
@example(suffix=".csv", data=b"\n# a comment\n", opts=ImportOptions(format="csv"))
def test_random_bytes_are_read_or_refused_in_one_line(folder, suffix, data, opts):
    _check(lambda: read_track(_write(folder, suffix, data), opts))


@FUZZ
@given(file=text_files, opts=options)
@example(file=(".csv", ONE_RUN_TIME_MISSING), opts=ImportOptions())  # ValueError: cannot convert float NaN
def test_mutated_tables_are_read_or_refused_in_one_line(folder, file, opts):
    suffix, data = file
    _check(lambda: read_track(_write(folder, suffix, data), opts))


@FUZZ
@given(suffix=st.sampled_from([".trk", ".xml", ".txt"]), data=mutated(TRK.encode()),
       opts=options.map(lambda o: ImportOptions(fps=o.fps, track_id=o.track_id)))
@example(suffix=".trk", data=TRK.replace('encoding="UTF-8"', 'encoding="nanUTF-8"').encode(),
         opts=ImportOptions())  # LookupError: unknown encoding
def test_mutated_tracker_projects_are_read_or_refused_in_one_line(folder, suffix, data, opts):
    _check(lambda: read_track(_write(folder, suffix, data), opts))


@FUZZ
@given(suffix=st.sampled_from([".trz", ".zip", ".csv"]), data=archives | damaged_archives, opts=options)
@example(suffix=".zip", data=DAMAGED_PHYPHOX, opts=ImportOptions())  # zlib.error
@example(suffix=".trz", data=DAMAGED_TRZ, opts=ImportOptions())  # zlib.error
@example(suffix=".trz", data=NAME_NOT_UTF8, opts=ImportOptions())  # UnicodeDecodeError
@example(suffix=".zip", data=NAME_NOT_UTF8, opts=ImportOptions())
@example(suffix=".trz", data=VERSION_6_4, opts=ImportOptions())  # NotImplementedError: zip file version 6.4
@example(suffix=".zip", data=VERSION_6_4, opts=ImportOptions())
def test_zips_of_random_members_are_read_or_refused_in_one_line(folder, suffix, data, opts):
    _check(lambda: read_track(_write(folder, suffix, data), opts))


@FUZZ
@given(file=text_files | st.tuples(st.sampled_from([".csv", ".txt"]), st.binary(max_size=300)))
def test_height_log_reader_reads_or_refuses_in_one_line(folder, file):
    suffix, data = file
    _check(lambda: read_height_log(_write(folder, suffix, data), horizontal=True))


impact_files = st.one_of(
    st.tuples(st.sampled_from([".csv", ".tsv", ".txt"]), st.sampled_from(sorted(IMPACT_SEEDS)).flatmap(
        lambda key: mutated(IMPACT_SEEDS[key].encode()))),
    st.tuples(st.sampled_from([".csv", ".txt"]), st.binary(max_size=300)),
    st.tuples(st.just(".zip"), st.lists(st.tuples(
        _member_names, st.sampled_from(sorted(IMPACT_SEEDS)).flatmap(lambda key: mutated(IMPACT_SEEDS[key].encode()))),
        max_size=3).map(lambda members: _zip([("meta/device.csv", b"property,value\n")] + members))),
    st.tuples(st.just(".zip"), damaged_archives))


@FUZZ
@given(file=impact_files, columns=st.none() | st.sampled_from(["time=impact_time_s[s]", "time=t[ms]", "y=x"]))
@example(file=(".zip", DAMAGED_PHYPHOX), columns=None)  # zlib.error
def test_impact_time_tables_are_read_or_refused_in_one_line(folder, file, columns):
    suffix, data = file
    _check(lambda: read_impact_table(_write(folder, suffix, data), columns))
