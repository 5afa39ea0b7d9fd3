"""Mitsuba's dictionary scene form, turned into Mitsuba 3 XML.

``snell.load_dict(d)`` writes the dictionary as XML with :func:`dict_to_xml`
and loads that text, so a dictionary scene goes through exactly the loader
(and the checks and error messages) that an XML file does. The XML puts one
element on a line; the line and column of a ``SceneError`` raised by
``load_dict`` point into this text, which ``snell.dict_to_xml(d)`` returns.

The rules are Mitsuba's:

* a nested dictionary with a ``'type'`` is an object; its tag (``bsdf``,
  ``shape``, ...) follows from the plugin name. Directly inside the scene the
  key becomes the object's ``id`` (unless the dictionary gives an ``'id'``);
  inside another object the key is the parameter's ``name``;
* ``{'type': 'ref', 'id': 'x'}`` refers to the object with id ``x``;
* ``{'type': 'rgb', 'value': [r, g, b]}`` (or a single number) is a colour;
  ``{'type': 'spectrum', 'value': v}`` is a spectrum: a number, a list of
  ``(wavelength, value)`` pairs, or ``'filename'`` instead of ``'value'``;
* ``bool``, ``int``, ``float`` and ``str`` values are ``<boolean>``,
  ``<integer>``, ``<float>`` and ``<string>``;
* a 4 x 4 matrix (nested lists, a numpy array, or a
  :class:`ScalarTransform4f`) is a ``<transform>``; three numbers (a list,
  tuple or numpy array, or a :class:`ScalarPoint3f`) are a ``<point>``.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, List, Mapping, Sequence
from xml.sax.saxutils import quoteattr

# Mitsuba 3's plugins by the tag they are declared with. Plugins Snell does
# not have still get their tag, so the loader reports them with its list of
# valid choices and a location.
_TAGS = {
    "bsdf": """diffuse dielectric thindielectric roughdielectric conductor roughconductor plastic
        roughplastic bumpmap normalmap blendbsdf mask twosided null polarizer retarder circular
        principled principledthin hair measured measured_polarized pplastic""",
    "shape": """obj ply serialized cube rectangle disk cylinder sphere bsplinecurve linearcurve
        sdfgrid shapegroup instance ellipsoids ellipsoidsmesh""",
    "emitter": "area point constant envmap spot projector directional directionalarea",
    "sensor": "perspective thinlens orthographic radiancemeter irradiancemeter distant batch",
    "film": "hdrfilm specfilm",
    "rfilter": "box tent gaussian mitchell catmullrom lanczos",
    "sampler": "independent stratified multijitter orthogonal ldsampler",
    "integrator": """direct path aov volpath volpathmis ptracer stokes moment depth prb prb_basic
        direct_projective prb_projective""",
    "texture": "bitmap checkerboard mesh_attribute volume",
    "spectrum": "blackbody uniform regular irregular d65 srgb",
    "medium": "homogeneous heterogeneous",
    "phase": "isotropic hg rayleigh sggx tabphase blendphase",
    "volume": "gridvolume constvolume",
}
PLUGIN_TAGS = {name: tag for tag, names in _TAGS.items() for name in names.split()}


class DictError(ValueError):
    """A dictionary that does not describe a scene (raised as SceneError)."""


def _number(v: Any) -> str:
    f = float(v)
    if not math.isfinite(f):
        raise DictError(f"{v!r} is not a finite number")
    return repr(f)


def _flat(v: Any) -> List[float]:
    """The numbers of a (nested) sequence or numpy array, row by row."""
    if hasattr(v, "tolist"):
        v = v.tolist()
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return [float(v)]
    if isinstance(v, (list, tuple)):
        out: List[float] = []
        for x in v:
            out.extend(_flat(x))
        return out
    raise DictError(f"{v!r} is not a number or a list of numbers")


def _shape(v: Any) -> tuple:
    if hasattr(v, "shape"):
        return tuple(v.shape)
    if isinstance(v, (list, tuple)):
        inner = {_shape(x) for x in v}
        if len(inner) == 1:
            return (len(v),) + inner.pop()
        return (len(v), None)
    return ()


def _matrix(v: Any) -> List[float] | None:
    """The 16 numbers of a 4 x 4 matrix value, or None if `v` is none."""
    m = getattr(v, "matrix", None)
    if m is not None and not callable(m):
        v = m
    if _shape(v) == (4, 4):
        return _flat(v)
    return None


def dict_to_xml(d: Mapping[str, Any]) -> str:
    """Mitsuba 3 XML (version 3.0.0) of the scene dictionary `d`."""
    if not isinstance(d, Mapping):
        raise DictError(f"load_dict expects a dict, not {type(d).__name__}")
    if d.get("type") != "scene":
        raise DictError("the top-level dictionary needs 'type': 'scene' (a single object cannot be loaded on its own)")
    lines = ['<scene version="3.0.0">']
    for key, value in d.items():
        if key == "type":
            continue
        _child(lines, key, value, 1, in_scene=True)
    lines.append("</scene>")
    return "\n".join(lines) + "\n"


def _attrs(**kv: Any) -> str:
    return "".join(f" {k}={quoteattr(str(v))}" for k, v in kv.items() if v is not None)


def _child(lines: List[str], key: str, value: Any, depth: int, in_scene: bool = False) -> None:
    pad = "    " * depth
    if not isinstance(key, str):
        raise DictError(f"dictionary keys must be strings, not {key!r}")
    if isinstance(value, Mapping):
        kind = value.get("type")
        if not isinstance(kind, str):
            raise DictError(f"{key!r}: a nested dictionary needs a 'type' (e.g. 'diffuse', 'rgb', 'ref')")
        if kind == "ref":
            rid = value.get("id")
            if not isinstance(rid, str):
                raise DictError(f"{key!r}: a reference needs an 'id' string")
            name = None if in_scene else key
            lines.append(f"{pad}<ref{_attrs(id=rid, name=name)}/>")
            return
        if kind == "rgb":
            _only(key, value, {"type", "value"})
            if "value" not in value:
                raise DictError(f"{key!r}: an 'rgb' value needs 'value'")
            nums = _flat(value["value"])
            if len(nums) not in (1, 3):
                raise DictError(f"{key!r}: an rgb 'value' is one number or three")
            lines.append(f"{pad}<rgb{_attrs(name=key, value=', '.join(_number(x) for x in nums))}/>")
            return
        if kind == "spectrum":
            _only(key, value, {"type", "value", "filename"})
            if "filename" in value:
                lines.append(f"{pad}<spectrum{_attrs(name=key, filename=value['filename'])}/>")
                return
            if "value" not in value:
                raise DictError(f"{key!r}: a 'spectrum' needs 'value' or 'filename'")
            lines.append(f"{pad}<spectrum{_attrs(name=key, value=_spectrum_text(key, value['value']))}/>")
            return
        tag = PLUGIN_TAGS.get(kind)
        if tag is None:
            raise DictError(
                f"{key!r}: unknown plugin type {kind!r}; Mitsuba's plugins are: " + ", ".join(sorted(PLUGIN_TAGS))
            )
        oid = value.get("id")
        if oid is None and in_scene:
            oid = key
        name = None if in_scene else key
        children = [(k, v) for k, v in value.items() if k not in ("type", "id")]
        if not children:
            lines.append(f"{pad}<{tag}{_attrs(type=kind, id=oid, name=name)}/>")
            return
        lines.append(f"{pad}<{tag}{_attrs(type=kind, id=oid, name=name)}>")
        for k, v in children:
            _child(lines, k, v, depth + 1)
        lines.append(f"{pad}</{tag}>")
        return
    if in_scene:
        raise DictError(f"{key!r}: only objects (dictionaries with a 'type') may stand directly in the scene")
    lines.append(pad + _property(key, value))


def _only(key: str, value: Mapping[str, Any], allowed: Iterable[str]) -> None:
    extra = sorted(set(value) - set(allowed))
    if extra:
        raise DictError(f"{key!r}: unexpected entries {extra}; expected {sorted(allowed)}")


def _spectrum_text(key: str, v: Any) -> str:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return _number(v)
    pairs: Sequence = v.tolist() if hasattr(v, "tolist") else v
    try:
        return ", ".join(f"{_number(w)}:{_number(x)}" for w, x in pairs)
    except (TypeError, ValueError) as e:
        raise DictError(f"{key!r}: a spectrum 'value' is a number or a list of (wavelength, value) pairs") from e


def _property(key: str, value: Any) -> str:
    if isinstance(value, bool):
        return f"<boolean{_attrs(name=key, value='true' if value else 'false')}/>"
    if isinstance(value, int) or type(value).__name__.startswith(("int", "uint")) and hasattr(value, "item"):
        if not isinstance(value, int):
            value = value.item()
            if isinstance(value, float):
                return f"<float{_attrs(name=key, value=_number(value))}/>"
        return f"<integer{_attrs(name=key, value=int(value))}/>"
    if isinstance(value, float) or (hasattr(value, "item") and _shape(value) == ()):
        return f"<float{_attrs(name=key, value=_number(value))}/>"
    if isinstance(value, str):
        return f"<string{_attrs(name=key, value=value)}/>"
    m = _matrix(value)
    if m is not None:
        return f"<transform{_attrs(name=key)}><matrix{_attrs(value=' '.join(_number(x) for x in m))}/></transform>"
    tag = "vector" if type(value).__name__ == "ScalarVector3f" else "point"
    if _shape(value) == (3,) or hasattr(value, "xyz"):
        nums = _flat(getattr(value, "xyz", value))
        return f"<{tag}{_attrs(name=key, value=', '.join(_number(x) for x in nums))}/>"
    raise DictError(
        f"{key!r}: cannot express {type(value).__name__} value {value!r} in a scene "
        "(expected a bool, int, float, str, 3 numbers, a 4 x 4 matrix or a dictionary with a 'type')"
    )
