"""Point layouts of 2D detectors, as data: which point is which in a detector's output.

A detector writes its points in a fixed order (OpenPose BODY_25 puts the neck second,
COCO-17 the left eye). A :class:`Layout` names those points with pinrecon's names, the
same names the human figure's keypoint maps use, so that one name means one point of
the body whatever the detector:

* COCO's names (``nose``, ``left_eye`` ... ``right_ankle``) for the COCO points;
* ``neck``: the midpoint of the shoulders (OpenPose BODY_25 and COCO-18 compute it so);
* ``mid_hip``: the midpoint of the hips (BODY_25, Halpe-26's ``hip``, H36M's pelvis);
* ``upper_neck``: the top of the neck, under the skull (BODY_25B's ``UpperNeck``,
  Halpe-26's and CrowdPose's ``neck``): about halfway between the shoulders' midpoint
  and the nose, well above the shoulders, so it is not ``neck``;
* ``head_top``: the top of the head (BODY_25B ``HeadTop``, Halpe ``head``,
  CrowdPose ``head``, H36M ``head``);
* ``left_big_toe``, ``left_small_toe``, ``left_heel`` and the right ones;
* MediaPipe's BlazePose points keep MediaPipe's names (``left_eye_inner``, ``mouth_left``,
  ``left_foot_index`` ...); its COCO points, heels and foot tips are on the human's
  ``mediapipe33`` map, its eye and mouth corners and hand points (pinky, index, thumb) on no map;
* points no figure carries keep a layout-specific name (``h36m_spine`` ...).

Whole-body layouts (Halpe-136, COCO-WholeBody-133) keep their body part only: the
first ``len(names)`` of their ``n_points`` points.

Layouts with the same number of points (BODY_25 and BODY_25B; COCO-17 and H36M-17) are
told apart by their geometry (:func:`pinrecon.layouts.detect.detect_layout`), or named
by the user (``--layout``). Each layout names the human keypoint map
(``models/keypoints/human_<map>.json``) that carries its points.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from pathlib import Path

from .._resources import model_path
from ..errors import InputError

__all__ = [
    "BOX",
    "LAYOUTS",
    "MEDIAPIPE_OFF_MAP",
    "Layout",
    "get_layout",
    "human_keypoint_map",
    "human_keypoint_maps",
    "human_map_for",
    "human_map_for_names",
    "known_point_names",
    "layout_from_names",
    "layouts_with",
    "normalise_point_name",
    "shared_point_names",
]

COCO_17 = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip",
    "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
)
BODY_25 = (
    "nose", "neck", "right_shoulder", "right_elbow", "right_wrist", "left_shoulder",
    "left_elbow", "left_wrist", "mid_hip", "right_hip", "right_knee", "right_ankle",
    "left_hip", "left_knee", "left_ankle", "right_eye", "left_eye", "right_ear", "left_ear",
    "left_big_toe", "left_small_toe", "left_heel", "right_big_toe", "right_small_toe", "right_heel",
)
COCO_18 = BODY_25[:8] + BODY_25[9:19]
BODY_25B = COCO_17 + (
    "upper_neck", "head_top", "left_big_toe", "left_small_toe", "left_heel",
    "right_big_toe", "right_small_toe", "right_heel",
)
HALPE_26 = COCO_17 + (
    "head_top", "upper_neck", "mid_hip", "left_big_toe", "right_big_toe", "left_small_toe",
    "right_small_toe", "left_heel", "right_heel",
)
WHOLEBODY_23 = COCO_17 + (
    "left_big_toe", "left_small_toe", "left_heel", "right_big_toe", "right_small_toe", "right_heel",
)
CROWDPOSE_14 = COCO_17[5:] + ("head_top", "upper_neck")
H36M_17 = (
    "mid_hip", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle",
    "h36m_spine", "h36m_thorax", "h36m_neck_nose", "head_top", "left_shoulder", "left_elbow",
    "left_wrist", "right_shoulder", "right_elbow", "right_wrist",
)

# MediaPipe Pose (BlazePose GHUM, 33 landmarks), in its PoseLandmark order; the names are
# MediaPipe's own, lower case. Its heel is the back of the heel; its foot index the tip of the
# foot (between the big and second toe), which is not OpenPose's big toe.
MEDIAPIPE_33 = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner", "right_eye",
    "right_eye_outer", "left_ear", "right_ear", "mouth_left", "mouth_right", "left_shoulder",
    "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_pinky",
    "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel", "right_heel",
    "left_foot_index", "right_foot_index",
)
#: MediaPipe's points on no keypoint map of the human, in MediaPipe's order: the eye and mouth
#: corners (with the nose, eyes and ears they would put 11 points on one rigid head whose detected
#: positions err together; bench/README.md, bench_video) and the hand points (no fingers)
MEDIAPIPE_OFF_MAP = (
    "left_eye_inner", "left_eye_outer", "right_eye_inner", "right_eye_outer", "mouth_left", "mouth_right",
    "left_pinky", "right_pinky", "left_index", "right_index", "left_thumb", "right_thumb",
)


@dataclass(frozen=True)
class Layout:
    """One detector layout.

    name : registry key (``--layout`` value), e.g. ``"body25b"``.
    title : how people write it, e.g. ``"OpenPose BODY_25B"``.
    n_points : points per person in the detector's files.
    names : pinrecon names of the first ``len(names)`` points (the body part).
    human_map : the human keypoint map carrying these points (``Figure.human(map)``).
    aliases : other spellings accepted by :func:`get_layout`.
    file_names : the names the detector itself writes (COCO ``categories`` etc.), used
        to recognise a layout from a file that lists its point names.
    """

    name: str
    title: str
    n_points: int
    names: tuple[str, ...]
    human_map: str | None
    aliases: tuple[str, ...] = ()
    file_names: tuple[str, ...] = ()


def _snake(s: str) -> str:
    s = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", str(s).strip())
    return re.sub(r"[^0-9a-z]+", "_", s.lower()).strip("_")


_OPENPOSE_25_FILE = (
    "Nose", "Neck", "RShoulder", "RElbow", "RWrist", "LShoulder", "LElbow", "LWrist", "MidHip",
    "RHip", "RKnee", "RAnkle", "LHip", "LKnee", "LAnkle", "REye", "LEye", "REar", "LEar",
    "LBigToe", "LSmallToe", "LHeel", "RBigToe", "RSmallToe", "RHeel",
)

LAYOUTS: dict[str, Layout] = {
    lay.name: lay
    for lay in (
        Layout("coco17", "COCO-17", 17, COCO_17, "coco17", ("coco", "coco_17"), COCO_17),
        Layout("body25", "OpenPose BODY_25", 25, BODY_25, "body25", ("body_25", "openpose"), _OPENPOSE_25_FILE),
        Layout("body25b", "OpenPose BODY_25B", 25, BODY_25B, "body25b", ("body_25b",)),
        Layout("coco18", "OpenPose COCO-18", 18, COCO_18, "body25", ("coco_18", "openpose_coco")),
        Layout("halpe26", "Halpe-26 (AlphaPose, RTMPose)", 26, HALPE_26, "halpe26", ("halpe_26", "halpe"),
               COCO_17 + ("head", "neck", "hip") + HALPE_26[20:]),
        Layout("halpe136", "Halpe-136 (body part: Halpe-26)", 136, HALPE_26, "halpe26", ("halpe_136",)),
        Layout("wholebody133", "COCO-WholeBody-133 (body and feet)", 133, WHOLEBODY_23, "body25",
               ("coco_wholebody", "wholebody", "coco133", "coco_133")),
        Layout("crowdpose14", "CrowdPose-14", 14, CROWDPOSE_14, "body25b", ("crowdpose", "crowdpose_14"),
               COCO_17[5:] + ("head", "neck")),
        Layout("h36m17", "Human3.6M-17", 17, H36M_17, "halpe26", ("h36m", "h36m_17", "human36m"),
               ("root", "right_hip", "right_knee", "right_foot", "left_hip", "left_knee", "left_foot",
                "spine", "thorax", "neck_base", "head", "left_shoulder", "left_elbow", "left_wrist",
                "right_shoulder", "right_elbow", "right_wrist")),
        Layout("mediapipe33", "MediaPipe Pose (BlazePose, 33 landmarks)", 33, MEDIAPIPE_33, "mediapipe33",
               ("mediapipe", "blazepose", "blazepose33", "mediapipe_33"), tuple(n.upper() for n in MEDIAPIPE_33)),
    )
}

BOX = Layout("box", "detection boxes (no keypoints)", 2, ("box_top_left", "box_bottom_right"), None, ("bbox", "boxes"))


def _key(name: str) -> str:
    return re.sub(r"[^0-9a-z]", "", str(name).lower())


def get_layout(name: str | Layout) -> Layout:
    """The layout called ``name`` (case, ``-`` and ``_`` ignored: ``BODY_25B`` is
    ``body25b``); an unknown name raises an InputError listing the valid ones."""
    if isinstance(name, Layout):
        return name
    k = _key(name)
    for lay in (*LAYOUTS.values(), BOX):
        if k == _key(lay.name) or k in {_key(a) for a in lay.aliases}:
            return lay
    raise InputError(
        f"unknown layout {name!r}; valid layouts are: "
        + ", ".join(f"{lay.name} ({lay.title}, {lay.n_points} points)" for lay in LAYOUTS.values())
        + ", box",
        field="layout",
    )


def layouts_with(n_points: int) -> list[Layout]:
    """The registered layouts whose files hold ``n_points`` points per person."""
    return [lay for lay in LAYOUTS.values() if lay.n_points == n_points]


def layout_from_names(file_names) -> Layout | None:
    """The registered layout whose detector writes exactly these point names (a COCO
    file's ``categories[].keypoints``), compared without case and punctuation."""
    keys = tuple(_key(n) for n in file_names)
    for lay in LAYOUTS.values():
        for cand in (lay.file_names, lay.names):
            if cand and len(cand) == len(keys) and tuple(_key(n) for n in cand) == keys:
                return lay
    return None


def normalise_point_name(name) -> str:
    """A point name from a file in pinrecon's snake_case (``LBigToe`` -> ``l_big_toe``)."""
    return _snake(name)


def known_point_names() -> set[str]:
    """Every point name of every registered layout (names a figure may lack without
    them being typos)."""
    out = set(BOX.names)
    for lay in LAYOUTS.values():
        out.update(lay.names)
    return out


def human_keypoint_maps() -> dict[str, Path]:
    """The human's bundled keypoint maps ``{name: path}`` (``models/keypoints/human_<name>.json``)."""
    files = sorted(model_path("keypoints").glob("human_*.json"))
    return {f.stem[len("human_"):].lower(): f for f in files}


def human_keypoint_map(name) -> Path:
    """The path of the human keypoint map ``name`` (a bundled map, case ignored, or a
    keypoint-map JSON file); anything else raises an InputError listing the bundled maps."""
    maps = human_keypoint_maps()
    if str(name).lower() in maps:
        return maps[str(name).lower()]
    path = Path(name)
    if path.is_file():
        return path
    raise InputError(
        f"unknown keypoint map {str(name)!r}: not a bundled map and no such file; the bundled maps of "
        f"'human' are: {', '.join(maps)} (or give a keypoint-map JSON file)",
        field="keypoints",
    )


def human_map_for(tracks) -> str:
    """The bundled human keypoint map for these tracks (one :class:`~pinrecon.Tracks` or
    several, e.g. one per camera): the map of their detector layout (``tracks.layout``, set
    by :func:`pinrecon.load_tracks`), else :func:`human_map_for_names` of their point names.
    ``Figure.human("auto", tracks=...)`` and the command line's ``--figure human`` choose
    with it."""
    seq = [tracks] if hasattr(tracks, "names") else list(tracks or [])
    seq = [t for t in seq if t is not None]
    for t in seq:
        lay = LAYOUTS.get(getattr(t, "layout", None) or "")
        if lay is not None and lay.human_map:
            return lay.human_map
    return human_map_for_names({n for t in seq for n in t.names})


def human_map_for_names(names) -> str:
    """The bundled human keypoint map carrying most of these point names, COCO-17 on a tie
    or when none carries any."""
    from ..figure_files import load_keypoint_map

    names = set(names)
    shared = {m: len(names & {k.name for k in load_keypoint_map(p)}) for m, p in human_keypoint_maps().items()}
    best = max(shared.values(), default=0)
    return "coco17" if best == 0 or shared.get("coco17") == best else max(shared, key=shared.get)


def shared_point_names(names, figure_names, *, what: str = "tracks", source=None) -> tuple[list[str], list[str]]:
    """``(shared, ignored)``: the ``names`` a figure with keypoints ``figure_names`` has,
    in order, and the others.

    Errors: a name that is no figure keypoint and no point of any registered layout but
    close to a figure keypoint (``left_wrst``, case ignored) is a typo, listed with its
    close matches; no shared name, or fewer than 4 (fewer than the figure has, for
    figures with fewer than 4), cannot place a figure.
    """
    names, fig_names = list(names), list(figure_names)
    shared = [n for n in names if n in fig_names]
    ignored = [n for n in names if n not in fig_names]
    known = known_point_names()
    lower = {str(n).lower(): n for n in fig_names}
    typos = []
    for n in ignored:
        close = [] if n in known else difflib.get_close_matches(str(n).lower(), list(lower), n=3, cutoff=0.85)
        if close:
            typos.append(f"{n!r} (did you mean {' or '.join(repr(lower[c]) for c in close)}?)")
    if typos:
        raise InputError(
            f"{what} name(s) that look like typos of figure keypoints: {'; '.join(typos)}. "
            f"Figure keypoints: {', '.join(map(str, fig_names[:60]))}",
            file=source,
            field="names",
        )
    hint = (f". A figure made from a BVH or URDF file names its keypoints after its joints: give it a keypoint map "
            f"that places the {what}' points on them (--keypoints MAP.json, e.g. {{\"keypoints\": {{\"left_shoulder\": "
            f"\"LeftArm\", ...}}}}; docs/formats.md, keypoint maps)")
    if not shared:
        raise InputError(
            f"the {what} and the figure share no keypoint name. {what} names: {names[:40]}; "
            f"figure keypoints: {fig_names[:60]}{hint}",
            file=source,
            field="names",
        )
    need = min(4, len(fig_names))
    if len(shared) < need:
        raise InputError(
            f"the {what} share only {len(shared)} point(s) with the figure ({', '.join(shared)}): at least {need} "
            f"are needed to place it. {what} names: {names[:40]}; figure keypoints: {fig_names[:60]}{hint}",
            file=source,
            field="names",
        )
    return shared, ignored
