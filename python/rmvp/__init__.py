"""rmvp from Python: polarized scenes of every layout rmvp reads as numpy arrays, the camera's
raw frames, reconstruction, evaluation and alignment. Each call is a thin layer over rmvp's
crates (the command line's code), with its conventions: OpenCV cameras (``x_cam = R x_world +
t``, pixel centres at ``(i + 0.5, j + 0.5)``), Stokes and AoP in the image frame (AoP from image
+x towards image +y, down). ``docs/python.md`` has a session and every array's shape and dtype.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field, fields
from typing import Any, Callable, Dict, List, Optional, Union

import numpy as np

from . import _rmvp
from .errors import InputError, MissingFileError, OptionError, RmvpError

__all__ = [
    "View",
    "Mesh",
    "Scene",
    "Frame",
    "Polarization",
    "Reconstruction",
    "read_scene",
    "read_release",
    "write_scene",
    "convert",
    "read_raw",
    "demosaic",
    "stokes",
    "aop_tangents",
    "reconstruct",
    "evaluate",
    "align",
    "LAYOUTS",
    "SPLITS",
    "RmvpError",
    "InputError",
    "MissingFileError",
    "OptionError",
]

__version__: str = _rmvp.__version__

#: The scene layouts rmvp reads and writes: its own, the official NeRSP loader's, RMVP3D's
#: original release and PANDORA's.
LAYOUTS = ("rmvp", "nersp", "rmvp3d", "pandora")

PathLike = Union[str, "os.PathLike[str]"]

log = logging.getLogger("rmvp")


@dataclass
class View:
    """One calibrated view and the images it has (None where it has not).

    Cameras follow OpenCV: ``x_cam = R @ x_world + t``, pixel ``(i, j)`` centred at
    ``(i + 0.5, j + 0.5)``. Images are ``(height, width)`` or ``(height, width, channels)``,
    row 0 at the top.
    """

    #: Unique name (``000``, ...), used for file names.
    name: str
    #: ``"train"`` (an input of reconstruction) or ``"eval"`` (held out).
    split: str
    #: Intrinsics, (3, 3) float64.
    K: np.ndarray
    #: World-to-camera rotation, (3, 3) float64, ``det R = +1``.
    R: np.ndarray
    #: World-to-camera translation, (3,) float64.
    t: np.ndarray
    #: Image width, pixels.
    width: int
    #: Image height, pixels.
    height: int
    #: OpenCV distortion ``k1, k2, p1, p2, k3``, (5,) float64.
    distortion: Optional[np.ndarray] = None
    #: Stokes S0, (H, W, 3) float32, linear RGB (1 channel for a mono camera).
    s0: Optional[np.ndarray] = None
    #: Stokes S1 (0 minus 90 degrees), like ``s0``.
    s1: Optional[np.ndarray] = None
    #: Stokes S2 (45 minus 135 degrees), like ``s0``.
    s2: Optional[np.ndarray] = None
    #: Angle of polarization, (H, W) float32, radians in [0, pi), image frame.
    aop: Optional[np.ndarray] = None
    #: Degree of polarization, (H, W) float32, 0 to 1.
    dop: Optional[np.ndarray] = None
    #: Object mask, (H, W) uint8, 0 background, 255 object.
    mask: Optional[np.ndarray] = None
    #: Ground-truth world-frame unit normals, (H, W, 3) float32, 0 outside the object.
    normals: Optional[np.ndarray] = None
    #: Ground-truth depth along the camera's z axis, (H, W) float32, 0 outside the object.
    depth: Optional[np.ndarray] = None
    #: The images behind the polarizers at 0, 45, 90, 135 degrees, (4, H, W[, C]) uint16.
    polarized: Optional[np.ndarray] = None
    #: Linear intensity per count of ``polarized``.
    polarized_scale: Optional[float] = None
    #: The 4x4 projection ``K [R | t]`` exactly as a source file gave it (IDR's ``world_mat``).
    projection: Optional[np.ndarray] = None

    @property
    def center(self) -> np.ndarray:
        """The camera centre in world coordinates, ``-R.T @ t``."""
        return -self.R.T @ self.t


@dataclass
class Mesh:
    """A triangle mesh: ``vertices`` (n, 3) float32 and ``faces`` (m, 3) uint32."""

    vertices: np.ndarray
    faces: np.ndarray


@dataclass
class Scene:
    """A scene: its views, the similarity from the unit sphere to the world, the ground-truth
    mesh where there is one, and free-form metadata."""

    views: List[View]
    #: The similarity mapping the reconstruction's unit sphere into the world (IDR/NeuS
    #: ``scale_mat``), (4, 4) float64.
    normalization: np.ndarray = field(default_factory=lambda: np.eye(4))
    #: Ground-truth mesh, world frame.
    mesh: Optional[Mesh] = None
    #: Provenance (generator, material, seeds, ...), kept through conversions.
    metadata: Dict[str, Any] = field(default_factory=dict)
    #: The layout the scene was read in (None for one built in Python).
    layout: Optional[str] = None

    def view(self, name: str) -> View:
        """The view called ``name``."""
        for v in self.views:
            if v.name == name:
                return v
        raise KeyError(name)

    @property
    def train_views(self) -> List[View]:
        """The views reconstruction trains on."""
        return [v for v in self.views if v.split == "train"]


def _scene_from(d: Dict[str, Any], layout: Optional[str]) -> Scene:
    names = {f.name for f in fields(View)}
    views = [View(**{k: v for k, v in view.items() if k in names}) for view in d["views"]]
    mesh = Mesh(**d["mesh"]) if d.get("mesh") is not None else None
    return Scene(views, d["normalization"], mesh, json.loads(d["metadata"]), layout)


_DTYPES = {
    "K": np.float64,
    "R": np.float64,
    "t": np.float64,
    "distortion": np.float64,
    "projection": np.float64,
    "mask": np.uint8,
    "polarized": np.uint16,
}


def _view_dict(view: View) -> Dict[str, Any]:
    def array(name: str, value: Any) -> Any:
        if isinstance(value, np.ndarray) or (name in _DTYPES and value is not None):
            return np.ascontiguousarray(value, dtype=_DTYPES.get(name, np.float32))
        return value

    return {f.name: array(f.name, getattr(view, f.name)) for f in fields(View)}


def _scene_dict(scene: Scene) -> Dict[str, Any]:
    views = [_view_dict(v) for v in scene.views]
    mesh = None
    if scene.mesh is not None:
        mesh = {
            "vertices": np.ascontiguousarray(scene.mesh.vertices, dtype=np.float32),
            "faces": np.ascontiguousarray(scene.mesh.faces, dtype=np.uint32),
        }
    return {
        "views": views,
        "normalization": np.ascontiguousarray(scene.normalization, dtype=np.float64),
        "mesh": mesh,
        "metadata": json.dumps(scene.metadata),
    }


def _scene_arg(scene: Union[Scene, PathLike]) -> Any:
    return _scene_dict(scene) if isinstance(scene, Scene) else os.fspath(scene)


def read_scene(path: PathLike) -> Scene:
    """The scene in folder ``path``, in whichever layout it is (``LAYOUTS``; detected as
    ``rmvp dataset info`` does). Raises :class:`MissingFileError` for a folder or file that is
    not there and :class:`InputError` naming the file for one that is broken."""
    d, layout = _rmvp.read_scene(os.fspath(path))
    return _scene_from(d, layout)


#: The splits of a release's views.
SPLITS = ("train", "eval")


def read_release(path: PathLike, split: str = "train") -> Dict[str, Scene]:
    """The views of ``split`` (``"train"``: the inputs of reconstruction, ``"eval"``: held out)
    of every object of the release in ``path`` (``rmvp dataset publish``), object by object,
    each a :class:`Scene` read from the object's ``rmvp/`` layout with only that split's views.
    Every file is first checked against the release's ``SHA256SUMS``: a release with any file
    changed, missing or unlisted raises :class:`InputError` naming each."""
    if split not in SPLITS:
        raise OptionError(f"split {split!r}: a release's splits are {', '.join(SPLITS)}")
    root = os.fspath(path)
    _matched, faults = _rmvp.check_listing(root, "SHA256SUMS")
    if faults:
        error = InputError(f"{root}: the release does not match its SHA256SUMS:\n" + "\n".join(faults))
        error.path = root
        raise error
    objects = sorted(
        entry.name
        for entry in os.scandir(root)
        if entry.is_dir() and os.path.isfile(os.path.join(entry.path, "build.json"))
    )
    release = {}
    for name in objects:
        scene = read_scene(os.path.join(root, name, "rmvp"))
        scene.views = [view for view in scene.views if view.split == split]
        release[name] = scene
    return release


def write_scene(scene: Union[Scene, PathLike], path: PathLike, layout: str = "rmvp") -> None:
    """Write ``scene`` (a :class:`Scene` or a scene folder) into the folder ``path`` in
    ``layout`` (one of ``LAYOUTS``); the index file last, so that an interrupted write is never
    taken for a scene."""
    _rmvp.write_scene(_scene_arg(scene), os.fspath(path), layout)


def convert(source: PathLike, destination: PathLike, layout: str, mirror_aop: bool = False) -> None:
    """Copy the scene in ``source`` into the new (or empty) folder ``destination`` in ``layout``,
    as ``rmvp dataset convert`` does; ``mirror_aop`` mirrors a scene whose AoP turns the other
    way (``rmvp dataset check`` tells)."""
    _rmvp.convert(os.fspath(source), os.fspath(destination), layout, mirror_aop)


def read_raw(path: PathLike, pixel_format: str, width: int = 2448, height: int = 2048) -> np.ndarray:
    """A raw frame file as the camera's samples, (H, W) uint16: a ``.png`` mosaic (8 or 16-bit
    grey) or a bare buffer (``.raw``, ``.bin``) in the GenICam ``pixel_format`` and size."""
    pixels, _bits = _rmvp.read_raw(os.fspath(path), pixel_format, width, height)
    return pixels


@dataclass
class Frame:
    """One raw frame processed as ``rmvp demosaic`` does; images are half the mosaic's size."""

    #: The images behind the polarizers at 0, 45, 90, 135 degrees (image frame), raw counts,
    #: (4, H, W) uint16 for the mono sensor, (4, H, W, 3) after colour demosaicing.
    angles: np.ndarray
    #: Stokes S0, S1, S2 in units of full scale, (H, W[, 3]) float32.
    s0: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    #: AoP of the channel-mean Stokes vector, (H, W) float32, radians in [0, pi).
    aop: np.ndarray
    #: DoP of the channel-mean Stokes vector, (H, W) float32.
    dop: np.ndarray
    #: Saturated polarizer angles per pixel (0 to 4), (H, W) uint8.
    saturated: np.ndarray
    #: Significant bits of the raw samples.
    bits: int


def demosaic(
    raw: np.ndarray,
    pixel_format: str,
    method: Optional[str] = None,
    saturation_aware: bool = False,
) -> Frame:
    """Split a raw polarization mosaic (H, W) into its four polarizer images, demosaic the
    colour sensor's Bayer (``method``: ``bilinear``, the default, ``edge-aware`` or ``vng``, as
    OpenCV names them), and compute Stokes, AoP and DoP, exactly as the command line and a
    capture do. ``pixel_format`` is the GenICam name (``Polarized8``, ``BayerRGPolarized12p``,
    ...); its bits bound the samples. ``saturation_aware`` drops saturated angles from the
    Stokes estimate."""
    samples = np.ascontiguousarray(raw, dtype=np.uint16)
    return Frame(**_rmvp.demosaic(samples, pixel_format, method, saturation_aware))


@dataclass
class Polarization:
    """Stokes images and the AoP and DoP of their channel mean."""

    s0: np.ndarray
    s1: np.ndarray
    s2: np.ndarray
    aop: np.ndarray
    dop: np.ndarray


def stokes(i0: np.ndarray, i45: np.ndarray, i90: np.ndarray, i135: np.ndarray) -> Polarization:
    """Stokes from four linear images behind polarizers at 0, 45, 90 and 135 degrees (image
    frame; one shape, (H, W) or (H, W, C)): ``S0 = (I0 + I45 + I90 + I135) / 2``, ``S1 = I0 -
    I90``, ``S2 = I45 - I135``; AoP ``0.5 atan2(S2, S1)`` in [0, pi)."""
    images = [np.ascontiguousarray(i, dtype=np.float32) for i in (i0, i45, i90, i135)]
    return Polarization(**_rmvp.stokes(*images))


def aop_tangents(view: View) -> "tuple[np.ndarray, np.ndarray]":
    """The tangents each pixel's AoP gives, as rmvp's geometric cue takes them: ``t = d x e``
    and ``e``, the polarization direction in the pixel ray's Stokes frame (``d`` the ray through
    the pixel's centre), world frame, each (H, W, 3) float64. Diffuse reflection puts the normal
    in the plane of ``d`` and ``e`` (``n . t = 0``), specular in that of ``d`` and ``t``. On the
    optical axis ``t`` is the official NeRSP loader's ``r1 sin(aop) - r2 cos(aop)`` reversed."""
    return _rmvp.aop_tangents(_view_dict(view))


@dataclass
class Reconstruction:
    """What :func:`reconstruct` did and where its results are."""

    #: The output folder.
    output: str
    #: Iterations trained so far (over every call on this folder).
    iteration: int
    #: The run's length.
    iterations: int
    #: The mesh (world frame), None until the run finishes.
    mesh: Optional[str]
    #: Per training view: the residuals of S0, S1, S2 and the AoP (``residuals.json``).
    residuals: Optional[Any]
    #: The loss log, one JSON object per iteration.
    log: str
    #: The checkpoint a later call resumes from.
    checkpoint: str

    @property
    def finished(self) -> bool:
        """Whether the run trained all its iterations and wrote its results."""
        return self.iteration >= self.iterations


def _log_progress(every: int) -> Callable[[Dict[str, Any]], None]:
    def report(step: Dict[str, Any]) -> None:
        it = step["iteration"] + 1
        if it == 1 or it % every == 0:
            log.info("iteration %d: loss %.4f, sharpness %.0f", it, step["loss"], step["inv_s"])
        if step.get("event"):
            log.warning("iteration %d: %s", it, step["event"])

    return report


def reconstruct(
    scene: Union[Scene, PathLike],
    output: PathLike,
    *,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    resume: bool = False,
    stop_after: Optional[int] = None,
    **options: Any,
) -> Reconstruction:
    """Reconstruct ``scene`` (a :class:`Scene` or a scene folder) into the folder ``output``,
    as ``rmvp recon`` does, with its options under their field names (``preset="dense"``,
    ``iters=3300``, ``min_sample_weight=1e-4``; ``rmvp recon --help`` lists them; an unknown
    name raises :class:`OptionError`).

    ``progress(step)`` is called after every iteration with the step's report (``iteration``,
    ``loss``, ``losses`` by term, ``inv_s``, ...); by default the ``rmvp`` logger says how it
    goes every 100 iterations. Ctrl-C stops after the iteration under way with a checkpoint and
    raises ``KeyboardInterrupt``; ``resume=True`` continues from it, ``stop_after`` trains at
    most that many iterations in this call.
    """
    callback = progress if progress is not None else _log_progress(100)
    out = os.fspath(output)
    iteration, iterations = _rmvp.reconstruct(
        _scene_arg(scene),
        out,
        json.dumps(options),
        lambda report: callback(json.loads(report)),
        resume,
        stop_after,
    )
    finished = iteration >= iterations
    residuals = None
    if finished:
        with open(os.path.join(out, "residuals.json"), encoding="utf-8") as f:
            residuals = json.load(f)
    return Reconstruction(
        output=out,
        iteration=iteration,
        iterations=iterations,
        mesh=os.path.join(out, "mesh.ply") if finished else None,
        residuals=residuals,
        log=os.path.join(out, "log.jsonl"),
        checkpoint=os.path.join(out, "checkpoint.bin"),
    )


def evaluate(
    pred: PathLike,
    gt: PathLike,
    scene: Optional[PathLike] = None,
    error_maps: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """The figures of ``rmvp eval --json``: accuracy, completeness, Chamfer and F-score of the
    mesh ``pred`` against ``gt`` (same frame and units), and with ``scene`` (a folder with
    ground-truth normals) the normal error per view and its mean (``normal_mae_deg``);
    ``error_maps`` is a folder for each view's error picture."""
    text = _rmvp.evaluate(
        os.fspath(pred),
        os.fspath(gt),
        None if scene is None else os.fspath(scene),
        None if error_maps is None else os.fspath(error_maps),
    )
    return json.loads(text)


def align(scan: PathLike, target: PathLike, output: PathLike) -> Dict[str, Any]:
    """Align the mesh ``scan`` onto ``target`` by a similarity (ICP with scale), as ``rmvp
    align`` does: the aligned scan and ``alignment.json`` go into ``output``; returns the
    alignment: ``scan_to_target`` (``s``, ``r``, ``t`` with ``x_target = s r x_scan + t``, and
    its 4x4 ``matrix``), its inverse and the residuals (``rms_point_to_plane``, ``median_distance``,
    ``inlier_ratio``)."""
    return json.loads(_rmvp.align(os.fspath(scan), os.fspath(target), os.fspath(output)))
