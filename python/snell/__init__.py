"""Snell: a physically based renderer for Mitsuba 3 XML scenes, from Python.

The names follow Mitsuba 3's, so that a script can switch by changing its
import::

    import snell as mi            # was: import mitsuba as mi
    scene = mi.load_file("scenes/cornell-box.xml", res=128)
    image = mi.render(scene, spp=64)          # numpy float32 (H, W, 3)

* :func:`load_file`, :func:`load_string`, :func:`load_dict` load a scene
  (``**params`` are the ``<default>`` parameters, the command line's ``-D``);
* :func:`render` renders it to a numpy array (H, W, C): the film's colour
  channels (R, G, B), then alpha and AOV channels if the scene has them, then
  S0..S3 (R, G, B each) in the polarized modes; :func:`channel_names` names
  them;
* :func:`write` and :func:`read` save and load images (EXR, PNG, PFM) as the
  command line writes them;
* errors in a scene raise :class:`SceneError` (a ``ValueError``) with
  ``file``, ``line`` and ``column``;
* rendering releases the GIL and stops on Ctrl-C (``KeyboardInterrupt``)
  within a fraction of a second.
"""

from __future__ import annotations

import math
import os
import sys
import xml.etree.ElementTree as ET
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _snell
from ._dict import DictError, dict_to_xml
from ._snell import SceneError

__all__ = [
    "Scene",
    "SceneError",
    "ScalarTransform4f",
    "ScalarPoint3f",
    "ScalarVector3f",
    "MODES",
    "load_file",
    "load_string",
    "load_dict",
    "dict_to_xml",
    "render",
    "channel_names",
    "write",
    "read",
    "set_variant",
    "variant",
    "variants",
    "cli_main",
    "Preview",
]

__version__ = "0.1.0"

#: What a light path carries (the command line's ``--mode``).
MODES = ("rgb", "spectral", "rgb-polarized", "spectral-polarized")

PathLike = Union[str, "os.PathLike[str]"]

# ---------------------------------------------------------------- variants

_VARIANTS = {
    "scalar_rgb": "rgb",
    "scalar_spectral": "spectral",
    "scalar_rgb_polarized": "rgb-polarized",
    "scalar_spectral_polarized": "spectral-polarized",
    "llvm_ad_rgb": "rgb",
    "llvm_ad_spectral": "spectral",
    "llvm_ad_rgb_polarized": "rgb-polarized",
    "llvm_ad_spectral_polarized": "spectral-polarized",
    "cuda_ad_rgb": "rgb",
    "cuda_ad_spectral": "spectral",
    "cuda_ad_rgb_polarized": "rgb-polarized",
    "cuda_ad_spectral_polarized": "spectral-polarized",
}
_variant = "scalar_rgb"


def variants() -> List[str]:
    """Mitsuba's variant names that :func:`set_variant` accepts."""
    return list(_VARIANTS)


def set_variant(name: str) -> None:
    """Choose the default ``mode`` of :func:`render` by a Mitsuba variant name.

    ``scalar_rgb`` / ``llvm_ad_rgb`` / ``cuda_ad_rgb`` render in ``rgb``,
    ``*_spectral`` in ``spectral``, ``*_polarized`` in the polarized modes.
    Snell always renders on the CPU's cores; the prefix only names the mode.
    """
    global _variant
    if name not in _VARIANTS:
        raise ValueError(f"unknown variant {name!r}; the variants are {', '.join(_VARIANTS)}")
    _variant = name


def variant() -> str:
    """The variant last set with :func:`set_variant` (default ``scalar_rgb``)."""
    return _variant


def _mode(mode: Optional[str]) -> str:
    return _VARIANTS[_variant] if mode is None else mode


# ---------------------------------------------------------------- transforms


class ScalarPoint3f(tuple):
    """A point (three numbers); in :func:`load_dict` it becomes ``<point>``."""

    def __new__(cls, *xyz: Any) -> "ScalarPoint3f":
        if len(xyz) == 1:
            xyz = tuple(np.asarray(xyz[0], dtype=float).reshape(-1).tolist())
        if len(xyz) != 3:
            raise ValueError(f"{cls.__name__} takes three numbers")
        return super().__new__(cls, (float(v) for v in xyz))


class ScalarVector3f(ScalarPoint3f):
    """A direction (three numbers); in :func:`load_dict` it becomes ``<vector>``."""


class _either:
    """A method callable on the class (starting from the identity, as in
    Mitsuba before 3.5: ``T.translate(v)``) or on an instance (composing,
    as in Mitsuba 3.5+: ``T().translate(v).scale(s)``)."""

    def __init__(self, f: Callable) -> None:
        self.f = f
        self.__doc__ = f.__doc__

    def __get__(self, obj: Any, cls: type) -> Callable:
        target = obj if obj is not None else cls()
        return self.f.__get__(target, cls)


class ScalarTransform4f:
    """A 4 x 4 affine transform, as Mitsuba's ``ScalarTransform4f``.

    Each method returns ``self`` composed with the new transform (the new
    one applied first), so ``T().translate(t).rotate(axis, 90)`` rotates
    then translates, as in Mitsuba. ``.matrix`` is the numpy 4 x 4 matrix;
    :func:`load_dict` writes it as ``<transform><matrix .../></transform>``.
    """

    def __init__(self, matrix: Any = None) -> None:
        m = np.identity(4) if matrix is None else np.array(getattr(matrix, "matrix", matrix), dtype=np.float64)
        if m.shape != (4, 4):
            raise ValueError(f"a transform is a 4 x 4 matrix, not of shape {m.shape}")
        self.matrix = m

    def __matmul__(self, other: "ScalarTransform4f") -> "ScalarTransform4f":
        if isinstance(other, ScalarTransform4f):
            return ScalarTransform4f(self.matrix @ other.matrix)
        p = np.asarray(other, dtype=np.float64)
        if p.shape == (3,):
            h = self.matrix @ np.append(p, 1.0)
            return ScalarPoint3f(h[:3] / h[3])
        return NotImplemented

    def __repr__(self) -> str:
        return f"ScalarTransform4f({self.matrix.tolist()!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ScalarTransform4f) and bool(np.array_equal(self.matrix, other.matrix))

    def _then(self, m: np.ndarray) -> "ScalarTransform4f":
        return ScalarTransform4f(self.matrix @ m)

    @_either
    def translate(self, v: Sequence[float]) -> "ScalarTransform4f":
        """Compose with a translation by `v`."""
        m = np.identity(4)
        m[:3, 3] = np.asarray(v, dtype=np.float64).reshape(3)
        return self._then(m)

    @_either
    def scale(self, v: Union[float, Sequence[float]]) -> "ScalarTransform4f":
        """Compose with a scaling by `v` (one number, or one per axis)."""
        s = np.broadcast_to(np.asarray(v, dtype=np.float64).reshape(-1), (3,))
        return self._then(np.diag([s[0], s[1], s[2], 1.0]))

    @_either
    def rotate(self, axis: Sequence[float], angle: float) -> "ScalarTransform4f":
        """Compose with a rotation of `angle` degrees about `axis` (right-handed)."""
        a = np.asarray(axis, dtype=np.float64).reshape(3)
        a = a / np.linalg.norm(a)
        t = math.radians(angle)
        c, s = math.cos(t), math.sin(t)
        x, y, z = a
        r = np.array(
            [
                [c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)],
            ]
        )
        m = np.identity(4)
        m[:3, :3] = r
        return self._then(m)

    @_either
    def look_at(self, origin: Sequence[float], target: Sequence[float], up: Sequence[float]) -> "ScalarTransform4f":
        """Compose with a camera frame at `origin` looking at `target` (+z
        forward, `up` projected to +y, +x to the left), as Mitsuba's."""
        o = np.asarray(origin, dtype=np.float64).reshape(3)
        d = np.asarray(target, dtype=np.float64).reshape(3) - o
        d = d / np.linalg.norm(d)
        left = np.cross(np.asarray(up, dtype=np.float64).reshape(3), d)
        n = np.linalg.norm(left)
        if n == 0:
            raise ValueError("look_at: `up` is parallel to the viewing direction")
        left = left / n
        new_up = np.cross(d, left)
        m = np.identity(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, o
        return self._then(m)

    def inverse(self) -> "ScalarTransform4f":
        """The inverse transform."""
        return ScalarTransform4f(np.linalg.inv(self.matrix))


# ---------------------------------------------------------------- scenes


class Scene:
    """A loaded scene: render it with :func:`render`; look inside with the
    methods below (as Mitsuba's ``scene.sensors()``, ``scene.emitters()``,
    ``scene.shapes()``)."""

    def __init__(self, native: Any, parameters: Dict[str, str], source: str) -> None:
        self._native = native
        self._parameters = parameters
        self._source = source

    def __repr__(self) -> str:
        w, h = self.size
        return (
            f"<snell.Scene {self._source!r}: {w}x{h}, {self.spp} spp, {len(self.shapes())} shapes, "
            f"{len(self.emitters())} emitters, integrator {self.integrator!r}>"
        )

    @property
    def path(self) -> str:
        """The file the scene was read from (for strings and dicts, the name errors use)."""
        return self._native.path

    @property
    def film_size(self) -> Tuple[int, int]:
        """(width, height) of the film (the camera's projection)."""
        return tuple(self._native.film_size)  # type: ignore[return-value]

    @property
    def crop(self) -> Tuple[int, int, int, int]:
        """(x, y, width, height) of the rendered window of the film."""
        return tuple(self._native.crop)  # type: ignore[return-value]

    @property
    def size(self) -> Tuple[int, int]:
        """(width, height) of the rendered image (the crop window)."""
        c = self._native.crop
        return (c[2], c[3])

    @property
    def spp(self) -> int:
        """The sampler's samples per pixel."""
        return self._native.spp

    @property
    def seed(self) -> int:
        """The sampler's seed."""
        return self._native.seed

    @property
    def integrator(self) -> str:
        """The integrator's plugin name (``path``, ``direct``, ``ptracer``, ``aov``, ``moment``)."""
        return self._native.integrator

    @property
    def parameters(self) -> Dict[str, str]:
        """The parameters the scene file declares with ``<default>``, with
        the values this load used (the defaults, or the ``**params`` given).
        Parameters of included files are not listed."""
        return dict(self._parameters)

    @property
    def warnings(self) -> List[str]:
        """Warnings the loader printed on the command line."""
        return list(self._native.warnings)

    def sensors(self) -> List[Dict[str, Any]]:
        """The scene's sensor (Snell renders one) with its film and sampler."""
        return [
            {
                "type": self._native.sensor,
                "film": {
                    "type": "hdrfilm",
                    "size": self.film_size,
                    "crop": self.crop,
                    "pixel_format": self._native.pixel_format,
                },
                "sampler": {"type": "independent", "sample_count": self.spp, "seed": self.seed},
            }
        ]

    def emitters(self) -> List[Dict[str, Any]]:
        """One ``{'type': plugin}`` per emitter (area lights included)."""
        return [{"type": t} for t in self._native.emitters]

    def shapes(self) -> List[Dict[str, Any]]:
        """One ``{'type', 'bsdf', 'emitter'}`` per shape; meshes of every
        kind (rectangle, cube, obj, ply, serialized) have type ``mesh``."""
        return [{"type": g, "bsdf": b, "emitter": e} for g, b, e in self._native.shapes]

    def bsdfs(self) -> List[str]:
        """The BSDF plugin of each material."""
        return list(self._native.bsdfs)

    def channel_names(self, mode: Optional[str] = None) -> List[str]:
        """The channels :func:`render` returns in `mode`."""
        return _names(self._native.channel_names(_mode(mode)))


def _params(params: Mapping[str, Any]) -> Dict[str, str]:
    out = {}
    for k, v in params.items():
        if isinstance(v, bool):
            v = "true" if v else "false"
        elif isinstance(v, (list, tuple)) or hasattr(v, "tolist") and np.ndim(v) > 0:
            v = ", ".join(repr(float(x)) for x in np.asarray(v).reshape(-1))
        out[k] = str(v)
    return out


def _declared(text: str, given: Dict[str, str]) -> Dict[str, str]:
    """The top-level <default> parameters of scene `text`, with `given` applied."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError:
        return {}
    out = {}
    for d in root.findall("default"):
        name = d.get("name")
        if name is not None:
            out[name] = given.get(name, d.get("value", ""))
    return out


def load_file(path: PathLike, **params: Any) -> Scene:
    """Load a Mitsuba 3 XML scene file.

    ``params`` set the parameters the scene declares with ``<default>`` (the
    command line's ``-D name=value``); numbers, booleans and 3-sequences
    are written as the XML expects. Raises :class:`SceneError` (with
    ``file``, ``line`` and ``column``) for a scene that cannot be loaded.

    >>> scene = snell.load_file("scenes/cornell-box.xml", res=64, spp=16)
    """
    path = os.fspath(path)
    given = _params(params)
    native = _snell.load_file(path, given)
    try:
        with open(path, encoding="utf-8") as f:
            declared = _declared(f.read(), given)
    except OSError:
        declared = {}
    return Scene(native, declared, path)


def load_string(text: str, base: Optional[PathLike] = None, **params: Any) -> Scene:
    """Load a scene from Mitsuba 3 XML text.

    Relative file names resolve against the folder of `base` (a file name
    that errors also show; default: ``<string>`` in the working folder).
    ``params`` as in :func:`load_file`.
    """
    name = os.fspath(base) if base is not None else os.path.join(os.getcwd(), "<string>")
    given = _params(params)
    native = _snell.load_string(text, name, given)
    return Scene(native, _declared(text, given), name)


def load_dict(d: Mapping[str, Any], base: Optional[PathLike] = None) -> Scene:
    """Load a scene from Mitsuba's dictionary form.

    The dictionary is written as Mitsuba 3 XML (:func:`dict_to_xml`) and
    loaded as :func:`load_string` loads text, so it is checked exactly as a
    file is; the ``line`` and ``column`` of a :class:`SceneError` point into
    ``dict_to_xml(d)``. Relative file names resolve against the working
    folder (or the folder of `base`)::

        scene = snell.load_dict({
            'type': 'scene',
            'integrator': {'type': 'path'},
            'sensor': {'type': 'perspective', 'fov': 40,
                       'to_world': snell.ScalarTransform4f().look_at(
                           origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                       'film': {'type': 'hdrfilm', 'width': 64, 'height': 64}},
            'light': {'type': 'constant'},
            'ball': {'type': 'sphere',
                     'bsdf': {'type': 'diffuse',
                              'reflectance': {'type': 'rgb', 'value': [0.8, 0.3, 0.2]}}},
        })
    """
    try:
        text = dict_to_xml(d)
    except DictError as e:
        err = SceneError(f"error: {e}")
        err.file, err.line, err.column, err.message, err.help = None, None, None, str(e), None
        raise err from None
    name = os.fspath(base) if base is not None else os.path.join(os.getcwd(), "<dict>")
    native = _snell.load_string(text, name, {})
    return Scene(native, {}, name)


# ---------------------------------------------------------------- rendering


_RANK = {c: i for i, c in enumerate("RGBAXYZ")}


def _order(names: Sequence[str]) -> List[int]:
    """The channel order of every array this package returns: the film's
    colour channels (R, G, B; Y; or X, Y, Z) as they come, then the others
    by layer name (alpha first, the Stokes layers S0..S3 last), R, G, B, A,
    X, Y, Z order within a layer. A render and the EXR it is written to
    (whose channels a file keeps in its own order) so read back alike."""
    main = 0
    while main < min(3, len(names)) and names[main] in ("R", "G", "B", "X", "Y", "Z"):
        main += 1

    def key(i: int) -> Tuple[bool, str, int, str]:
        prefix, _, comp = names[i].rpartition(".")
        return (prefix in ("S0", "S1", "S2", "S3"), prefix, _RANK.get(comp, len(_RANK)), comp)

    return list(range(main)) + sorted(range(main, len(names)), key=key)


def _array(data: bytes, height: int, width: int, names: Sequence[str]) -> np.ndarray:
    a = np.frombuffer(data, dtype=np.float32).reshape(height, width, len(names))
    order = _order(names)
    if order == list(range(len(names))):
        return a.copy()
    return np.ascontiguousarray(a[:, :, order])


def _names(names: Sequence[str]) -> List[str]:
    return [names[i] for i in _order(names)]


def render(
    scene: Scene,
    spp: Optional[int] = None,
    seed: Optional[int] = 0,
    mode: Optional[str] = None,
    threads: Optional[int] = None,
    progress: Optional[Callable[[float, np.ndarray], Any]] = None,
    passes: Optional[int] = None,
) -> np.ndarray:
    """Render `scene` and return the image as a float32 array (H, W, C).

    * ``spp``: samples per pixel (None or 0: the scene's sampler's);
    * ``seed``: the sampler's seed (as Mitsuba's ``mi.render``, 0 by
      default; None keeps the scene's);
    * ``mode``: ``rgb``, ``spectral``, ``rgb-polarized`` or
      ``spectral-polarized`` (None: from :func:`set_variant`, ``rgb``);
    * ``threads``: worker threads (None: all cores);
    * ``progress(fraction, image_so_far)``: called after each pass with the
      fraction of samples taken and the image of those samples; an
      exception it raises stops the render and is raised here;
    * ``passes``: how many passes (default 1, or 4 with ``progress``).

    The channels are those :func:`channel_names` gives: the film's colour
    channels (R, G, B), alpha and AOV channels if the scene has them, and in
    the polarized modes S0..S3 (``S1.R`` ...; S1 > 0 is horizontal
    polarization in the camera's frame). The pixels are bit-identical to the
    EXR that ``snell render SCENE --spp N --seed S --mode M`` writes.

    The GIL is released while rendering; Ctrl-C stops the render within a
    fraction of a second and raises ``KeyboardInterrupt``.
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"render() needs a snell.Scene, not {type(scene).__name__}")
    if spp == 0:
        spp = None
    if spp is not None and spp < 0:
        raise ValueError(f"spp={spp} is negative")
    if seed is not None and seed < 0:
        raise ValueError(f"seed={seed} is negative")
    if threads is not None and not 0 <= threads <= 4096:
        raise ValueError(f"threads={threads}: give 1 to 4096 worker threads (None or 0: all cores)")
    if passes is None:
        passes = 4 if progress is not None else 1
    on_pass = None
    if progress is not None:

        def on_pass(fraction: float, data: bytes, height: int, width: int, names: List[str]) -> None:
            progress(fraction, _array(data, height, width, names))

    data, height, width, names, _interrupted = _snell.render(
        scene._native, _mode(mode), spp, seed, threads or 0, max(1, int(passes)), on_pass
    )
    return _array(data, height, width, names)


def channel_names(what: Union[Scene, PathLike], mode: Optional[str] = None) -> List[str]:
    """The channel names of a render of scene `what` in `mode`, or of the
    image file `what` as :func:`read` returns it."""
    if isinstance(what, Scene):
        return what.channel_names(mode)
    return _names(_snell.read(os.fspath(what))[3])


def _default_channels(c: int) -> List[str]:
    if c == 1:
        return ["Y"]
    if c == 3:
        return ["R", "G", "B"]
    if c == 4:
        return ["R", "G", "B", "A"]
    raise ValueError(f"an image of {c} channels needs their names: write(array, path, channels=[...])")


def write(array: Any, path: PathLike, channels: Optional[Sequence[str]] = None) -> None:
    """Write an image array (H, W, C) or (H, W) as the command line does.

    ``.exr``: linear float32 with every channel; ``.png``: 8-bit sRGB
    (clamped), ``.pfm``: linear float32, colour only. `channels` names the
    channels (default by count: Y; R, G, B; R, G, B, A); an array from
    :func:`render` is named by ``channel_names(scene, mode)``.
    """
    a = np.asarray(array, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3:
        raise ValueError(f"an image is (H, W, C) or (H, W), not of shape {a.shape}")
    names = list(channels) if channels is not None else _default_channels(a.shape[2])
    if len(names) != a.shape[2]:
        raise ValueError(f"{len(names)} channel names for an image of {a.shape[2]} channels")
    a = np.ascontiguousarray(a)
    _snell.write(a.tobytes(), a.shape[0], a.shape[1], names, os.fspath(path))


def read(path: PathLike) -> np.ndarray:
    """Read an image as a float32 array (H, W, C): EXR with every channel
    (in :func:`channel_names` order), PFM, or PNG/JPEG (values / 255)."""
    data, height, width, names, _ = _snell.read(os.fspath(path))
    return _array(data, height, width, names)


def cli_main() -> None:
    """The ``snell`` command (``snell render SCENE ...``), as the Rust binary."""
    sys.exit(_snell.cli_main(["snell"] + sys.argv[1:]))


from ._preview import Preview  # noqa: E402

# Location attributes exist on every SceneError (None when not known).
for _name in ("file", "line", "column", "message", "help"):
    setattr(SceneError, _name, None)
del _name
