"""load_dict (Mitsuba's dictionary form) against load_file of the same
scene written as XML by hand: the same image, bit for bit."""

import numpy as np
import pytest

import snell
from snell import ScalarTransform4f as T

XML = """<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="4"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="24"/><integer name="height" value="20"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf>
    <emitter type="constant"><rgb name="radiance" value="0.2, 0.3, 0.4"/></emitter>
    <shape type="sphere">
        <point name="center" x="-0.6" y="0" z="0"/>
        <float name="radius" value="0.5"/>
        <bsdf type="roughconductor">
            <string name="material" value="Au"/>
            <float name="alpha" value="0.2"/>
        </bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="3"/><translate x="0" y="0" z="-1"/></transform>
        <ref id="grey"/>
    </shape>
    <shape type="sphere">
        <transform name="to_world"><scale value="0.3"/><translate x="0.7" y="0.5" z="0.2"/></transform>
        <bsdf type="diffuse">
            <texture type="checkerboard" name="reflectance">
                <rgb name="color0" value="0.9, 0.1, 0.1"/>
                <spectrum name="color1" value="0.25"/>
            </texture>
        </bsdf>
        <emitter type="area"><rgb name="radiance" value="2, 2, 1"/></emitter>
    </shape>
</scene>
"""

DICT = {
    "type": "scene",
    "integrator": {"type": "path", "max_depth": 4},
    "sensor": {
        "type": "perspective",
        "fov": 45.0,
        "to_world": T().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
        "sampler": {"type": "independent", "sample_count": 8},
        "film": {"type": "hdrfilm", "width": 24, "height": 20, "rfilter": {"type": "box"}},
    },
    "grey": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}},
    "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [0.2, 0.3, 0.4]}},
    "gold": {
        "type": "sphere",
        "center": [-0.6, 0, 0],
        "radius": 0.5,
        "bsdf": {"type": "roughconductor", "material": "Au", "alpha": 0.2},
    },
    "wall": {
        "type": "rectangle",
        "to_world": np.array(T().translate([0, 0, -1]).scale(3).matrix),
        "bsdf": {"type": "ref", "id": "grey"},
    },
    "lamp": {
        "type": "sphere",
        "to_world": T().translate([0.7, 0.5, 0.2]).scale(0.3),
        "bsdf": {
            "type": "diffuse",
            "reflectance": {
                "type": "checkerboard",
                "color0": {"type": "rgb", "value": [0.9, 0.1, 0.1]},
                "color1": {"type": "spectrum", "value": 0.25},
            },
        },
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [2, 2, 1]}},
    },
}


def test_load_dict_renders_as_load_file_of_its_xml(tmp_path):
    path = tmp_path / "scene.xml"
    path.write_text(XML)
    from_file = snell.render(snell.load_file(path), seed=4)
    d = snell.load_dict(DICT)
    assert [s["type"] for s in d.shapes()] == ["sphere", "mesh", "sphere"]
    assert d.size == (24, 20)
    from_dict = snell.render(d, seed=4)
    assert from_dict.shape == (20, 24, 3)
    assert from_dict.max() > 0
    assert np.array_equal(from_dict, from_file), f"max difference {np.abs(from_dict - from_file).max()}"


def test_dict_to_xml_writes_mitsuba_xml():
    xml = snell.dict_to_xml(DICT)
    assert '<ref id="grey" name="bsdf"/>' in xml
    assert '<rgb name="reflectance" value="0.5, 0.5, 0.5"/>' in xml
    assert '<texture type="checkerboard" name="reflectance">' in xml
    assert '<shape type="rectangle" id="wall">' in xml
    assert '<spectrum name="color1" value="0.25"/>' in xml
    assert '<boolean name="b" value="true"/>' in snell.dict_to_xml({"type": "scene", "i": {"type": "path", "b": True}})


def test_transform_helpers_match_mitsuba():
    # Mitsuba composes left to right: T().translate(t).scale(s) scales first.
    m = T().translate([1, 2, 3]).scale(2).matrix
    assert np.allclose(m @ [1, 1, 1, 1], [3, 4, 5, 1])
    # the class-level form of older Mitsuba versions starts from the identity
    assert T.translate([1, 2, 3]) == T().translate([1, 2, 3])
    r = T().rotate([0, 0, 1], 90).matrix
    assert np.allclose(r @ [1, 0, 0, 1], [0, 1, 0, 1])
    # look_at: +z towards the target, +y up, origin at the eye
    la = T().look_at(origin=[1, 2, 3], target=[1, 2, 10], up=[0, 1, 0]).matrix
    assert np.allclose(la @ [0, 0, 1, 1], [1, 2, 4, 1])
    assert np.allclose(la @ [0, 1, 0, 0], [0, 1, 0, 0])
    assert np.allclose((T().scale(2).inverse() @ T().scale(2)).matrix, np.identity(4))
    with pytest.raises(ValueError):
        T(np.zeros((3, 3)))
