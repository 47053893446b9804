"""What was tracked, drawn on the video's own frames: a contact sheet (PNG) and an annotated clip (H.264 MP4).

On each frame are drawn the tracked ball (a circle at the tracked centre and radius, coloured by the
frame's quality flag: :data:`QUALITY_COLOURS_BGR`), the fitted flights mapped back to pixels (the
trajectory's heights are −row × scale, so a fitted height h lies on row −h / scale, or is taken back
through a plane target's map; the column follows the tracked centres), the floor line and a scale bar
with its length in cm at the scale used. The contact sheet shows a grid of frames chosen to show the
release, every impact (the frames on either side of it) and every apex of the fitted flights, the first
and the last frame, each labelled with its frame number, time and quality flag, under a legend and a
caption: what the tracker found and, for a refused clip, the reason.

Frames are read by :func:`decoded_frames` (:class:`dropfit.video.decode.VideoFile`: rotation applied).
"""

from __future__ import annotations

import dataclasses
import textwrap
from fractions import Fraction

import numpy as np

from ..errors import InputError, shown_path
from ..physics import flight_height
from .calibrate import keystoned_rows
from .decode import VideoFile
from .opencv import cv2
from .track import (QUALITY_BLURRED, QUALITY_DUPLICATE, QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OFF_TRACK,
                    QUALITY_OK, QUALITY_PARTIAL, QUALITY_SHADED, usable_rows)

#: Colour (blue, green, red) of the circle drawn around the ball, by quality flag; a lost ball has none.
QUALITY_COLOURS_BGR = {QUALITY_OK: (60, 200, 60), QUALITY_BLURRED: (230, 170, 0), QUALITY_PARTIAL: (0, 150, 255),
                       QUALITY_SHADED: (0, 215, 255), QUALITY_OCCLUDED: (220, 60, 220),
                       QUALITY_DUPLICATE: (160, 160, 160), QUALITY_OFF_TRACK: (0, 0, 255)}
#: Colour of the fitted flights' curve, of the floor line and of the scale bar (blue, green, red).
CURVE_COLOUR_BGR = (0, 230, 230)
FLOOR_COLOUR_BGR = (40, 40, 230)
SCALE_COLOUR_BGR = (255, 255, 255)
#: Tiles of a contact sheet by default, and the box each frame is fitted into, px (width, height).
SHEET_TILES = 16
TILE_BOX_PX = (320, 240)
SHEET_COLUMNS = 4
#: Height of a tile's label strip and of a caption line, px.
LABEL_HEIGHT_PX = 18
CAPTION_LINE_PX = 18
#: Longest scale bar, as a fraction of the frame height; its length is the longest of these that fits, cm.
SCALE_BAR_FRACTION = 0.4
SCALE_BAR_LENGTHS_CM = (100, 50, 20, 10, 5, 2, 1, 0.5, 0.2, 0.1)
#: Smallest radius of the ball's circle as drawn, px: a ball a few px across in a scaled-down frame stays visible.
MIN_DRAWN_RADIUS_PX = 5.0
#: Points of the fitted curve per flight.
CURVE_POINTS = 200
#: Sub-pixel bits of OpenCV's drawing (coordinates in 1/16 px): circles and curves lie where they are measured.
_SHIFT = 4
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_FONT_SCALE = 0.4
#: OpenCV's fonts are ASCII: the symbols dropfit's messages use, spelled out.
_ASCII = {"≥": ">=", "≤": "<=", "×": "x", "σ": "sigma", "–": "-", "—": "-", "²": "^2", "…": "...", "±": "+-",
          "°": " deg", "µ": "u", "√": "sqrt", "₁": "1", "ρ": "rho", "’": "'"}


# --- reading frames (to be replaced by dropfit.video.decode) -------------------------------------

def decoded_frames(path, indices=None):
    """Decode a video once, in order, and yield the frames asked for, as the phone shows them.

    Parameters
    ----------
    path : str or pathlib.Path
        The video (MJPEG AVI, H.264 MP4/MOV, … whatever FFmpeg reads).
    indices : iterable of int, optional
        Frames to yield, counted from 0 in decoding order as the tracker counts them; by default every
        frame. Decoding stops after the last one asked for.

    Yields
    ------
    (int, numpy.ndarray)
        Frame index and the frame (height, width, 3), uint8, blue-green-red, rotation applied.
    """
    wanted = None if indices is None else set(int(index) for index in indices)
    last = None if wanted is None else max(wanted, default=-1)
    with VideoFile(path) as video:
        for index, _, image in video.frames():
            if last is not None and index > last:
                return
            if wanted is None or index in wanted:
                yield index, image


def frame_rate(path):
    """The video's frame rate in frames/s of its container (a :class:`fractions.Fraction`)."""
    with VideoFile(path) as video:
        rate = video.info.container_fps
    if not rate:
        raise InputError(f"{shown_path(path)}: the video states no frame rate, so no clip can be written at its rate")
    return Fraction(rate)


# --- what is drawn --------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class OverlayScene:
    """What was tracked and fitted, in the pixels of the video's frames.

    Attributes
    ----------
    table : pandas.DataFrame
        The tracked table (:func:`dropfit.video.track.track_video`): per frame ``frame``, ``time_s``,
        ``x_px``, ``y_px``, ``radius_px`` (px), ``quality``.
    frame_time_s : numpy.ndarray
        Time of each row of ``table`` in the trajectory's time base (capture time), s; a frame the
        trajectory does not hold (a duplicate, a refused clip) keeps the tracked table's time.
    flights : pandas.DataFrame or None
        The fitted flights (``t_start_s``, ``t_end_s``, ``t_apex_s`` in s, ``y_apex_m`` in m), or None.
    impacts : pandas.DataFrame or None
        The impacts (``t_touchdown_s``, ``t_liftoff_s``, s), or None.
    drag_k_per_m, gravity_m_s2 : float
        The flights' drag parameter (1/m) and g (m/s²).
    scale_m_per_px : float or None
        The scale used, m/px; None when the clip was refused before it was calibrated.
    scale_source : str or None
        Where the scale came from (``given``, ``ruler``, ``gravity``, ``diameter``).
    floor_row_px : float or None
        Image row of the floor, px.
    keystone : (float, float) or None
        A ruler's keystone κ (1/px) and its row r₀ (px): heights are of rows rectified with them
        (:func:`dropfit.video.calibrate.rectify_rows`), mapped back to image rows here.
    plane : (numpy.ndarray, numpy.ndarray, float) or None
        A plane target's image→plane homography (3×3, to m), the plane's unit vector down the drop (m)
        and the ratio of the plane's scale at the drop to ``scale_m_per_px``: heights are of the plane's
        rows, mapped back to image rows through the homography here.
    caption : list of str
        Lines shown above a contact sheet: what was tracked and, for a refused clip, why it was refused.
    """

    table: object
    frame_time_s: np.ndarray
    flights: object = None
    impacts: object = None
    drag_k_per_m: float = 0.0
    gravity_m_s2: float = 0.0
    scale_m_per_px: float | None = None
    scale_source: str | None = None
    floor_row_px: float | None = None
    keystone: tuple | None = None
    plane: tuple | None = None
    caption: tuple = ()

    def image_row_px(self, height_m, column_px):
        """The image row (px) of a height (m) in image column ``column_px`` (px): −h / scale, with a ruler's
        keystone put back, or the row where that column meets the plane's line of that height."""
        rows = -np.asarray(height_m, dtype=float) / self.scale_m_per_px  # heights are −row × scale
        if self.plane is None:
            return keystoned_rows(rows, *self.keystone) if self.keystone else rows
        homography, down, scale_ratio = self.plane
        down_m = rows * scale_ratio * self.scale_m_per_px  # the plane's coordinate down the drop
        # along a column the plane point is (a + r b) / (c + r d), r the row: solve down · it = down_m for r
        start = np.outer(np.asarray(column_px, dtype=float), homography[:, 0]) + homography[:, 2]
        step = homography[:, 1]
        return (down_m * start[:, 2] - start[:, :2] @ down) / (step[:2] @ down - down_m * step[2])

    def tracked_column_px(self, time_s):
        """Column (px) of the tracked centre at times ``time_s`` (s), interpolated between tracked frames."""
        usable = usable_rows(self.table)
        return np.interp(time_s, self.frame_time_s[usable], self.table["x_px"].to_numpy(float)[usable])

    def fitted_row_px(self, time_s):
        """Image row (px) of the fitted flight at times ``time_s`` (s), in the tracked centre's column; NaN
        outside every flight."""
        time_s = np.asarray(time_s, dtype=float)
        rows = np.full(time_s.shape, np.nan)
        if self.flights is None or self.scale_m_per_px is None:
            return rows
        for flight in self.flights.itertuples(index=False):
            inside = (time_s >= flight.t_start_s) & (time_s <= flight.t_end_s)
            height = flight_height(time_s[inside], flight.t_apex_s, flight.y_apex_m, self.drag_k_per_m,
                                   self.gravity_m_s2)
            rows[inside] = self.image_row_px(height, self.tracked_column_px(time_s[inside]))
        return rows

    def fitted_path_px(self):
        """The fitted flights as image points: columns and rows (px), NaN between flights, where the
        ball was tracked (a close-up does not show the fall it was fitted from)."""
        if self.flights is None or self.scale_m_per_px is None:
            return np.empty(0), np.empty(0)
        times = self.frame_time_s[usable_rows(self.table)]
        xs, ys = [], []
        for flight in self.flights.itertuples(index=False):
            start, end = max(flight.t_start_s, times.min()), min(flight.t_end_s, times.max())
            if end <= start:
                continue
            grid = np.linspace(start, end, CURVE_POINTS)
            xs += [self.tracked_column_px(grid), [np.nan]]
            ys += [self.fitted_row_px(grid), [np.nan]]
        return (np.concatenate(xs), np.concatenate(ys)) if xs else (np.empty(0), np.empty(0))


def overlay_scene(table, trajectory=None, flights=None, impacts=None, analysis=None, reason=None):
    """Gather what the overlay draws from a tracked table and whatever of the analysis there is.

    Parameters
    ----------
    table : pandas.DataFrame
        The tracked table (:func:`dropfit.video.track.track_video`, or ``track.csv``).
    trajectory : xarray.Dataset, optional
        The measured trajectory (its ``frame``, ``time`` and attributes: scale in m/px, floor in m).
    flights, impacts : pandas.DataFrame, optional
        The analysis' flights and impacts tables.
    analysis : dict, optional
        The analysis summary (``analysis.json``): ``drag_k_per_m`` (1/m), ``gravity_m_s2`` (m/s²),
        ``contact_height_m`` (m).
    reason : str, optional
        Why the clip was refused (the one-line message).

    Returns
    -------
    OverlayScene
    """
    frame_time = table["time_s"].to_numpy(float).copy()
    attrs = dict(trajectory.attrs) if trajectory is not None else {}
    if trajectory is not None and "frame" in trajectory:
        rows = np.searchsorted(table["frame"].to_numpy(), trajectory["frame"].values)
        frame_time[rows] = trajectory["time"].values
    scale = attrs.get("scale_m_per_px")
    floor_m = attrs.get("floor_m")
    if floor_m is None and analysis and analysis.get("contact_height_m") is not None \
            and attrs.get("ball_radius_m") is not None:
        floor_m = analysis["contact_height_m"] - attrs["ball_radius_m"]  # the contact height is the floor + radius
    analysis = analysis or {}
    keystone = (attrs["keystone_per_px"], attrs["keystone_row_px"]) if "keystone_per_px" in attrs else None
    plane = (np.reshape(attrs["plane_homography"], (3, 3)), np.asarray(attrs["plane_down"], dtype=float),
             attrs["plane_scale_m_per_px"] / scale) if "plane_homography" in attrs and scale else None
    return OverlayScene(
        table=table, frame_time_s=frame_time, flights=flights, impacts=impacts,
        drag_k_per_m=float(analysis.get("drag_k_per_m") or 0.0), gravity_m_s2=float(analysis.get("gravity_m_s2") or 0.0),
        scale_m_per_px=scale, scale_source=attrs.get("scale_source"),
        floor_row_px=attrs.get("floor_row_px", -floor_m / scale if floor_m is not None and scale else None),
        keystone=keystone, plane=plane, caption=tuple(tracking_caption(table, reason)))


def tracking_caption(table, reason=None):
    """Lines saying what the tracker found (how often, with which flags) and, for a refused clip, why."""
    counts = table["quality"].value_counts()
    found = len(table) - int(counts.get(QUALITY_LOST, 0))
    flags = ", ".join(f"{flag} {int(counts.get(flag, 0))}" for flag in (*QUALITY_COLOURS_BGR, QUALITY_LOST))
    usable = int(np.count_nonzero(usable_rows(table)))
    lines = [f"ball found in {found} of {len(table)} frames ({found / max(len(table), 1):.0%}), measured cleanly "
             f"in {usable} ({usable / max(len(table), 1):.0%}): {flags}"]
    if reason:
        lines.append(f"refused: {reason}")
    return lines


def _ascii(text):
    """``text`` as OpenCV's fonts can draw it."""
    text = "".join(_ASCII.get(char, char) for char in str(text))
    return text.encode("ascii", "replace").decode("ascii")


def _put_text(image, text, origin, colour=(255, 255, 255)):
    cv2.putText(image, _ascii(text), origin, _FONT, _FONT_SCALE, colour, 1, cv2.LINE_AA)


def _fixed(value):
    """Pixel coordinate(s) as OpenCV's sub-pixel integers (:data:`_SHIFT` bits)."""
    return np.round(np.asarray(value, dtype=float) * (1 << _SHIFT)).astype(np.int32)


def scale_bar_cm(scale_m_per_px, frame_height_px):
    """Length in cm of the scale bar: the longest of :data:`SCALE_BAR_LENGTHS_CM` within
    :data:`SCALE_BAR_FRACTION` of the frame's height (px) at ``scale_m_per_px`` (m/px)."""
    limit_m = SCALE_BAR_FRACTION * frame_height_px * scale_m_per_px
    return next((cm for cm in SCALE_BAR_LENGTHS_CM if cm / 100 <= limit_m), SCALE_BAR_LENGTHS_CM[-1])


def annotate_frame(frame, scene, row, zoom=1.0):
    """A frame with what was tracked and fitted drawn on it.

    Parameters
    ----------
    frame : numpy.ndarray
        The video frame (height, width, 3), uint8, blue-green-red; not changed.
    scene : OverlayScene
        What to draw.
    row : int
        The frame's row of ``scene.table`` (its frame number).
    zoom : float
        Size of the result relative to the frame (the drawing is done at that size, so it stays sharp).

    Returns
    -------
    numpy.ndarray
        The annotated frame, ``zoom`` times the size of ``frame``.
    """
    height, width = frame.shape[:2]
    size = (max(1, round(width * zoom)), max(1, round(height * zoom)))
    image = frame.copy() if size == (width, height) else cv2.resize(frame, size, interpolation=cv2.INTER_AREA)

    def to_image(value):  # pixel centres are at integers in both images; a frame pixel spans zoom pixels here
        return (np.asarray(value, dtype=float) + 0.5) * zoom - 0.5

    if scene.floor_row_px is not None:
        floor = _fixed(to_image(scene.floor_row_px))
        cv2.line(image, (0, int(floor)), (_fixed(size[0] - 1), int(floor)), FLOOR_COLOUR_BGR, 1, cv2.LINE_8, _SHIFT)
    columns, rows = scene.fitted_path_px()
    for piece_x, piece_y in zip(np.split(columns, np.flatnonzero(np.isnan(columns))),
                                np.split(rows, np.flatnonzero(np.isnan(rows)))):
        finite = np.isfinite(piece_x) & np.isfinite(piece_y)
        if np.count_nonzero(finite) >= 2:
            points = np.stack([_fixed(to_image(piece_x[finite])), _fixed(to_image(piece_y[finite]))], axis=1)
            cv2.polylines(image, [points], False, CURVE_COLOUR_BGR, 1, cv2.LINE_8, _SHIFT)
    ball = scene.table.iloc[row] if row < len(scene.table) else None  # a frame the tracker did not decode: no ball
    colour = None if ball is None else QUALITY_COLOURS_BGR.get(ball["quality"])
    if colour is not None and np.isfinite(ball["x_px"]) and np.isfinite(ball["y_px"]):
        centre = (int(_fixed(to_image(ball["x_px"]))), int(_fixed(to_image(ball["y_px"]))))
        radius = ball["radius_px"] * zoom if np.isfinite(ball["radius_px"]) else 0.0
        cv2.circle(image, centre, int(_fixed(max(radius, MIN_DRAWN_RADIUS_PX))), colour, 2, cv2.LINE_8, _SHIFT)
    if scene.scale_m_per_px:
        bar_cm = scale_bar_cm(scene.scale_m_per_px, height)
        length = bar_cm / 100 / scene.scale_m_per_px * zoom
        top, left = 0.05 * size[1], 6
        cv2.line(image, (left, round(top)), (left, round(top + length)), SCALE_COLOUR_BGR, 2)
        _put_text(image, f"{bar_cm:g} cm", (left + 4, round(top + 10)), SCALE_COLOUR_BGR)
    return image


# --- contact sheet and annotated clip ------------------------------------------------------------

def _nearest_row(times, time_s):
    return int(np.nanargmin(np.abs(times - time_s)))


def _tracked_bounces(rows_px, radius_px):
    """Positions in ``rows_px`` (the clean frames' centre rows, px, pointing down) of the ball's lowest points
    between rises of at least its radius (``radius_px``, px; 3 px when unknown): the bounces a refused clip shows,
    the deepest first."""
    from scipy.signal import find_peaks

    prominence = radius_px if np.isfinite(radius_px) and radius_px > 0 else 3.0
    peaks, properties = find_peaks(np.asarray(rows_px, dtype=float), prominence=prominence)
    return peaks[np.argsort(-properties["prominences"])].tolist()


def sheet_frames(scene, tiles=SHEET_TILES):
    """The frames (rows of ``scene.table``) a contact sheet shows, in order.

    First come the frames that tell the story: the first frame, the release (the first frame measured
    cleanly), the last frame, then per impact the apex of the flight before it and the frames just
    before touchdown and just after lift-off (without a fit, a refused clip: the ball's lowest and highest
    tracked points, then the lowest point of each bounce the tracked rows show); the rest are spread evenly
    over the clip.

    Parameters
    ----------
    scene : OverlayScene
    tiles : int
        How many frames at most.

    Returns
    -------
    list of int
    """
    table, times = scene.table, scene.frame_time_s
    count = len(table)
    usable = np.flatnonzero(usable_rows(table))
    story = [0, int(usable[0]) if usable.size else 0, count - 1]
    if scene.flights is not None and scene.impacts is not None:
        impacts = list(scene.impacts.itertuples(index=False))
        for number, flight in enumerate(scene.flights.itertuples(index=False)):
            story.append(_nearest_row(times, flight.t_apex_s))
            if number < len(impacts):  # the last frame before touchdown, the first after lift-off
                story += [max(int(np.searchsorted(times, impacts[number].t_touchdown_s)) - 1, 0),
                          min(int(np.searchsorted(times, impacts[number].t_liftoff_s)), count - 1)]
    elif usable.size:  # a refused clip: the bounces the tracked rows show, lowest points first
        rows = table["y_px"].to_numpy(float)[usable]
        story += [int(usable[np.argmax(rows)]), int(usable[np.argmin(rows)])]  # rows point down: the lowest point
        story += [int(usable[i]) for i in _tracked_bounces(rows, float(np.nanmedian(table["radius_px"])))]
    chosen = list(dict.fromkeys(story))[:tiles]
    for index in np.round(np.linspace(0, count - 1, tiles)).astype(int):
        if len(chosen) >= min(tiles, count):
            break
        if int(index) not in chosen:
            chosen.append(int(index))
    spare = (index for index in range(count) if index not in chosen)
    while len(chosen) < min(tiles, count):
        chosen.append(next(spare))
    return sorted(chosen)


def _tile(frame, scene, row):
    """One frame of the sheet: annotated, fitted into :data:`TILE_BOX_PX` under its label."""
    box_width, box_height = TILE_BOX_PX
    zoom = min(box_width / frame.shape[1], box_height / frame.shape[0])
    image = annotate_frame(frame, scene, row, zoom)
    tile = np.zeros((LABEL_HEIGHT_PX + box_height, box_width, 3), np.uint8)
    top, left = LABEL_HEIGHT_PX + (box_height - image.shape[0]) // 2, (box_width - image.shape[1]) // 2
    tile[top:top + image.shape[0], left:left + image.shape[1]] = image
    ball = scene.table.iloc[row]
    _put_text(tile, f"#{int(ball['frame'])}  {scene.frame_time_s[row]:.4f} s  {ball['quality']}",
              (4, LABEL_HEIGHT_PX - 5), QUALITY_COLOURS_BGR.get(ball["quality"], (255, 255, 255)))
    return tile


def _header(scene, width, title):
    """The legend and the caption over the sheet's width."""
    characters = max(20, width // 7)  # Hershey simplex at 0.4: about 7 px a character
    lines = [line for text in (title, *scene.caption) if text for line in textwrap.wrap(_ascii(text), characters)]
    header = np.zeros((CAPTION_LINE_PX * (len(lines) + 1) + 6, width, 3), np.uint8)
    x = 4
    legend = [(flag, colour) for flag, colour in QUALITY_COLOURS_BGR.items()]
    legend += [("fitted flights", CURVE_COLOUR_BGR), ("floor", FLOOR_COLOUR_BGR)]
    if scene.scale_m_per_px:
        legend.append((f"scale bar ({scene.scale_source}, {1e3 * scene.scale_m_per_px:.4g} mm/px)",
                       SCALE_COLOUR_BGR))
    for name, colour in legend:
        cv2.rectangle(header, (x, 5), (x + 10, 15), colour, -1)
        _put_text(header, name, (x + 14, 14), colour)
        x += 24 + cv2.getTextSize(_ascii(name), _FONT, _FONT_SCALE, 1)[0][0]
    for number, line in enumerate(lines, start=2):
        _put_text(header, line, (4, CAPTION_LINE_PX * number - 4))
    return header


def contact_sheet(video, scene, tiles=SHEET_TILES, title=""):
    """A grid of annotated frames (:func:`sheet_frames`) under a legend and the caption.

    Parameters
    ----------
    video : str or pathlib.Path
        The video the table was tracked from.
    scene : OverlayScene
        What to draw.
    tiles : int
        How many frames at most; :data:`SHEET_COLUMNS` a row.
    title : str
        First caption line (e.g. the video's name).

    Returns
    -------
    image : numpy.ndarray
        The sheet (height, width, 3), uint8, blue-green-red: a header, then rows of tiles of
        :data:`TILE_BOX_PX` plus a :data:`LABEL_HEIGHT_PX` label each.
    rows : list of int
        The frames shown (rows of ``scene.table``), in order.
    """
    rows = sheet_frames(scene, tiles)
    frames = dict(decoded_frames(video, rows))
    shown = [row for row in rows if row in frames]  # a damaged last frame the tracker read may not decode here
    columns = min(SHEET_COLUMNS, max(len(shown), 1))
    tiles_images = [_tile(frames[row], scene, row) for row in shown]
    tile_height, tile_width = LABEL_HEIGHT_PX + TILE_BOX_PX[1], TILE_BOX_PX[0]
    grid = np.zeros((tile_height * -(-len(shown) // columns), tile_width * columns, 3), np.uint8)
    for number, image in enumerate(tiles_images):
        top, left = tile_height * (number // columns), tile_width * (number % columns)
        grid[top:top + tile_height, left:left + tile_width] = image
    return np.concatenate([_header(scene, grid.shape[1], title), grid]), shown


def write_annotated_clip(video, path, scene):
    """Write every frame of ``video``, annotated (:func:`annotate_frame`), as H.264 MP4 at the video's
    container rate (a frame's height and width cut to even numbers, as H.264's 4:2:0 needs)."""
    import av

    with av.open(str(path), "w") as output:
        stream = output.add_stream("libx264", rate=frame_rate(video).limit_denominator(1001))
        stream.pix_fmt = "yuv420p"
        for index, frame in decoded_frames(video):
            image = annotate_frame(frame, scene, index)
            image = image[: image.shape[0] // 2 * 2, : image.shape[1] // 2 * 2]
            if index == 0:
                stream.height, stream.width = image.shape[:2]
            for packet in stream.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="bgr24")):
                output.mux(packet)
        for packet in stream.encode():
            output.mux(packet)
