"""What a clip shows and how it is filmed: the configuration dataclasses.

All lengths in the scene are in metres in the *drop plane*: the vertical
plane through the ball's path, X to the right and Y up, origin on the floor
at the drop line (the ball's release X).  Pixel quantities are given at full
resolution and multiplied by :attr:`ClipConfig.downscale` when rendering.
Colours are RGB triples in 0-255.  Frame rates are in Hz and may be
:class:`fractions.Fraction` (e.g. ``Fraction(30000, 1001)`` for 29.97 fps).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from fractions import Fraction

RGB = tuple[float, float, float]


@dataclass(frozen=True)
class BallStyle:
    """The ball's physics (a :mod:`refsim` preset) and look.

    Parameters
    ----------
    model : str
        refsim ball preset ("tennis", "table_tennis", "rubber", "steel", ...).
    radius_m : float or None
        Radius in m; None keeps the preset's.
    drag_coefficient : float or None
        C_d of its quadratic air drag; None keeps the preset's (a real ball's differs from any nominal value).
    colour_rgb : tuple
        Base colour (RGB 0-255) of the lit ball.
    ambient : float
        Brightness of the unlit side relative to the lit side (0-1).
    specular : float
        Strength of the highlight (0 matte, ~0.4 glossy plastic).
    seam : bool
        Draw a tennis ball's seam (a white saddle curve that turns with the spin).
    """

    model: str = "tennis"
    radius_m: float | None = None
    drag_coefficient: float | None = None
    colour_rgb: RGB = (205, 220, 60)
    ambient: float = 0.6
    specular: float = 0.0
    seam: bool = False


@dataclass(frozen=True)
class SceneStyle:
    """The static room: wall, board, clutter, floor, and the ball's shadows.

    Parameters
    ----------
    wall_rgb : tuple
        Wall colour (RGB).
    wall_texture : float
        Relative amplitude of the wall's blotchy texture (0.02 = 2 %).
    board : bool
        A white board (with a grey frame) behind the drop line.
    clutter : int
        Number of clutter objects: posters, furniture blobs, door-frame edges.
    floor : {"wood", "table", "plain"}
        Floor texture: wooden planks, a wooden table top (one board, fine
        grain), or a plain grey floor.
    floor_rgb : tuple
        Mean floor colour (RGB).
    wall_base_above_floor_frac : float
        The wall's base lies this fraction of the frame height above the
        floor's row at the drop line (the floor recedes to the wall).
    wall_shadow : float
        Darkening (0-1) of the ball's shadow on the wall at its core.
    wall_shadow_offset_r : tuple
        Shadow centre minus ball centre in ball radii (right, down); about
        (0.5, 0.6) makes the shadow touch and merge with the ball.
    wall_shadow_softness_r : float
        Penumbra width of the wall shadow in ball radii.
    floor_shadow : float
        Darkening (0-1) of the ball's shadow on the floor when the ball
        touches it; it fades and widens with height.
    floor_shadow_fade_m : float
        Height (m) over which the floor shadow fades by 1/e.
    """

    wall_rgb: RGB = (200, 200, 196)
    wall_texture: float = 0.02
    board: bool = False
    clutter: int = 0
    floor: str = "wood"
    floor_rgb: RGB = (150, 105, 65)
    wall_base_above_floor_frac: float = 0.06
    wall_shadow: float = 0.35
    wall_shadow_offset_r: tuple[float, float] = (0.45, 0.55)
    wall_shadow_softness_r: float = 0.35
    floor_shadow: float = 0.5
    floor_shadow_fade_m: float = 0.15


@dataclass(frozen=True)
class HandStyle:
    """The hand that holds, releases and optionally catches the ball.

    Parameters
    ----------
    hold_s : float
        The ball is held still for this long (s) from the clip's start and
        released at rest at ``hold_s``.
    visible : bool
        Draw the hand (skin, fingers, forearm to the frame edge).
    visible_at_release : bool
        Draw it while it holds and releases the ball too (False: the clip
        shows the release without a hand, e.g. from above the frame).
    skin_rgb : tuple
        Skin colour (RGB).
    arm_angle_deg : float
        Direction of the forearm from the hand, counter-clockwise from the
        +X axis in the drop plane (90 = straight up to the top edge).
    away_m : tuple
        Displacement (X, Y in m) of the hand after the release, reached in
        ``away_s`` (it usually leaves the frame).
    away_s : float
        Duration (s) of the hand's move away.
    catch_after_impact : int or None
        Catch the ball at the apex after this impact (1-based); None: no catch.
    catch_approach_s : float
        The catching hand comes in from ``away_m`` during this time (s).
    """

    hold_s: float = 1.5
    visible: bool = True
    visible_at_release: bool = True
    skin_rgb: RGB = (222, 170, 138)
    arm_angle_deg: float = 70.0
    away_m: tuple[float, float] = (0.25, 0.6)
    away_s: float = 0.6
    catch_after_impact: int | None = None
    catch_approach_s: float = 0.5


@dataclass(frozen=True)
class CameraSetup:
    """Where the camera looks and how it is rotated.

    Parameters
    ----------
    scale_px_per_m : float
        Image scale in the drop plane at full resolution (px per m) before
        any tilt.
    drop_column_frac : float
        Column of the drop line as a fraction of the displayed width.
    floor_row_frac : float
        Row of the floor at the drop line as a fraction of the displayed
        height (before tilt).
    pitch_deg, yaw_deg, roll_deg : float
        Camera rotation about its x (right), y (down) and z (optical) axes
        in degrees: a pinhole camera not square to the drop plane.  The image
        is re-centred so that the middle of the drop stays where it was.
    horizontal_fov_deg : float
        Horizontal field of view of the displayed frame (degrees); sets the
        focal length of the tilt homography.
    """

    scale_px_per_m: float = 900.0
    drop_column_frac: float = 0.5
    floor_row_frac: float = 0.9
    pitch_deg: float = 0.0
    yaw_deg: float = 0.0
    roll_deg: float = 0.0
    horizontal_fov_deg: float = 65.0

    @property
    def tilted(self) -> bool:
        """True when the camera is not square to the drop plane."""
        return any(a != 0.0 for a in (self.pitch_deg, self.yaw_deg, self.roll_deg))


@dataclass(frozen=True)
class FrameTiming:
    """Capture and container timing.

    Parameters
    ----------
    capture_fps : Fraction or float
        True capture rate (Hz).
    frames_per_capture : int
        Every captured frame is written this many times (2: a 60 fps
        container holding true 30 Hz motion, every other frame a repeat).
    pts_jitter_s : float
        Standard deviation (s) of the capture-time jitter that phones write
        into the timestamps (clipped to a quarter period); 0 for steady timing.
    drop_probability : float
        Probability that a capture is lost (its timestamp gap stays in a
        variable-frame-rate container).
    exposure_s : float
        Exposure time (s); the ball is blurred over it.  0: instantaneous.
    max_blur_samples : int
        Most sub-frame samples averaged per frame (the number used grows with
        the ball's motion during the exposure, one per ~px).
    slow_motion : int
        The container presents the captures this many times slower than
        they were taken (4: 120 fps captured, stored at 30 fps, as phones
        store slow motion); its sound track is slowed with it.
    """

    capture_fps: Fraction | float = Fraction(30)
    frames_per_capture: int = 1
    pts_jitter_s: float = 0.0
    drop_probability: float = 0.0
    exposure_s: float = 0.0
    max_blur_samples: int = 24
    slow_motion: int = 1


@dataclass(frozen=True)
class SensorEffects:
    """Sensor noise and lighting.

    Parameters
    ----------
    noise_sd_dn : float
        Standard deviation of the additive sensor noise (digital numbers, 0-255 scale).
    flicker : float
        Relative amplitude of the lighting's flicker at twice the mains
        frequency (0.1 = +-10 % for an instantaneous exposure).
    mains_hz : float
        Mains frequency (Hz); the light flickers at twice it.
    exposure_drift : float
        Relative amplitude of a slow auto-exposure drift.
    exposure_drift_period_s : float
        Period (s) of that drift.
    vignetting : float
        Relative darkening at the frame corners.
    """

    noise_sd_dn: float = 2.0
    flicker: float = 0.0
    mains_hz: float = 50.0
    exposure_drift: float = 0.0
    exposure_drift_period_s: float = 7.0
    vignetting: float = 0.15


@dataclass(frozen=True)
class Ruler:
    """A ruler or tape measure in the drop plane.

    Parameters
    ----------
    kind : {"ruler", "tape"}
        A ruler (cm and mm ticks, a number at every cm) or a tape measure
        (yellow, black cm ticks with small numbers, large numbers every 10 cm).
    length_m, width_m : float
        Length and width in m.
    zero_m : tuple
        (X, Y) in m of the zero mark on the ruler's tick edge.
    upright : bool
        True: the scale runs up (+Y) from the zero; False: it lies along +X.
    colour_rgb, ink_rgb : tuple
        Body and marking colours (RGB).
    ticks_on_rows : bool
        Draw each tick as one whole pixel row (upright, untilted only): cm
        ticks 4 or 5 px apart at 450 px/m, as phone sharpening leaves them.
    """

    kind: str = "ruler"
    length_m: float = 0.3
    width_m: float = 0.03
    zero_m: tuple[float, float] = (-0.25, 0.0)
    upright: bool = True
    colour_rgb: RGB = (60, 170, 90)
    ink_rgb: RGB = (20, 20, 20)
    ticks_on_rows: bool = False


@dataclass(frozen=True)
class Marker:
    """A printed ArUco marker in the drop plane.

    Parameters
    ----------
    marker_id : int
        Id in ``dictionary``.
    side_m : float
        Side of the black square (m), without the white paper margin.
    centre_m : tuple
        (X, Y) of the marker's centre in m.
    dictionary : str
        Name of the cv2.aruco predefined dictionary.
    """

    marker_id: int = 0
    side_m: float = 0.08
    centre_m: tuple[float, float] = (-0.3, 0.3)
    dictionary: str = "DICT_4X4_50"


@dataclass(frozen=True)
class Checkerboard:
    """A printed checkerboard in the drop plane.

    Parameters
    ----------
    squares : tuple
        (columns, rows) of squares.
    square_m : float
        Side of a square in m.
    centre_m : tuple
        (X, Y) of the board's centre in m.
    """

    squares: tuple[int, int] = (7, 5)
    square_m: float = 0.025
    centre_m: tuple[float, float] = (0.3, 0.4)


@dataclass(frozen=True)
class ClipConfig:
    """Everything about one clip.

    Parameters
    ----------
    width_px, height_px : int
        Displayed frame size at full resolution (px); portrait clips are
        taller than wide.
    rotation_deg : {0, 90, 180, 270}
        Display-matrix rotation, counter-clockwise, as PyAV's
        ``VideoStream.set_display_rotation`` takes it and ``VideoFrame.rotation``
        reads it back (mod 360): the stored frame rotated by it is the
        displayed frame.  270 is a phone filmed upright (FFmpeg's "rotate"
        tag and OpenCV's ``CAP_PROP_ORIENTATION_META`` say 90).
    downscale : float
        Multiplies every pixel size (frame, scale) to render small fast clips.
    drop_height_m : float
        Height of the ball's bottom above the floor at the release (m).
    g_m_s2 : float
        Gravity (m/s^2).
    duration_s : float or None
        Clip length (s); None: until 0.6 s after the ball rests or 0.8 s
        after the catch.
    codec : str
        Encoder ("libx264", "libx265" for HEVC, "mpeg4", "mjpeg").
    crf : int
        Constant rate factor for libx264 and libx265 (quality; 0 is lossless).
    encoder_preset : str
        libx264 / libx265 speed preset.
    bit_depth : int
        Bits per sample: 8, or 10 with libx265 (a phone's HDR video).
    ball, scene, hand, camera, timing, sensor
        See :class:`BallStyle`, :class:`SceneStyle`, :class:`HandStyle`,
        :class:`CameraSetup`, :class:`FrameTiming`, :class:`SensorEffects`.
    rulers, markers, checkerboards : tuple
        Scale objects in the drop plane.
    """

    width_px: int = 1920
    height_px: int = 1080
    rotation_deg: int = 0
    downscale: float = 1.0
    drop_height_m: float = 1.0
    g_m_s2: float = 9.81
    duration_s: float | None = None
    codec: str = "libx264"
    crf: int = 18
    encoder_preset: str = "veryfast"
    bit_depth: int = 8
    ball: BallStyle = field(default_factory=BallStyle)
    scene: SceneStyle = field(default_factory=SceneStyle)
    hand: HandStyle = field(default_factory=HandStyle)
    camera: CameraSetup = field(default_factory=CameraSetup)
    timing: FrameTiming = field(default_factory=FrameTiming)
    sensor: SensorEffects = field(default_factory=SensorEffects)
    rulers: tuple[Ruler, ...] = ()
    markers: tuple[Marker, ...] = ()
    checkerboards: tuple[Checkerboard, ...] = ()

    def scaled(self, downscale: float) -> "ClipConfig":
        """A copy rendered at ``downscale`` times the full resolution."""
        return replace(self, downscale=downscale)

    def clean(self) -> "ClipConfig":
        """A copy without noise, blur, flicker, drift, vignetting or timing jitter (for exact checks)."""
        return replace(self, sensor=replace(self.sensor, noise_sd_dn=0.0, flicker=0.0, exposure_drift=0.0,
                                            vignetting=0.0),
                       timing=replace(self.timing, exposure_s=0.0, pts_jitter_s=0.0, drop_probability=0.0))

    @property
    def frame_size_px(self) -> tuple[int, int]:
        """Displayed (width, height) in px after the downscale, rounded to even numbers for 4:2:0 chroma."""
        return (2 * max(8, round(self.width_px * self.downscale / 2)),
                2 * max(8, round(self.height_px * self.downscale / 2)))
