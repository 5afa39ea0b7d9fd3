"""Every kind of scene error raises snell.SceneError (a ValueError) with
its location and the command line's message; nothing panics."""

import subprocess

import pytest

import snell
from conftest import snell_command

GOOD_HEAD = """<scene version="3.0.0">
    <sensor type="perspective">
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
    </sensor>
"""

# (name, scene text, line, column or None, words in the message)
CASES = [
    ("xml syntax", GOOD_HEAD + "    <shape type=\"sphere\">\n</scene>\n", 6, 1, ""),
    ("unknown plugin", GOOD_HEAD + "    <shape type=\"teapot\"/>\n</scene>\n", 5, 5, "teapot"),
    ("unknown element", GOOD_HEAD + "    <shaep type=\"sphere\"/>\n</scene>\n", 5, 5, "shaep"),
    ("not a number", GOOD_HEAD + "    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"big\"/>\n    </shape>\n</scene>\n", 6, None, "big"),
    ("unused parameter", GOOD_HEAD + "    <shape type=\"sphere\">\n        <float name=\"radiuss\" value=\"1\"/>\n    </shape>\n</scene>\n", 6, None, "radiuss"),
    ("missing reference", GOOD_HEAD + "    <shape type=\"sphere\">\n        <ref id=\"nowhere\"/>\n    </shape>\n</scene>\n", 6, None, "nowhere"),
    ("missing mesh file", GOOD_HEAD + "    <shape type=\"obj\">\n        <string name=\"filename\" value=\"no-such.obj\"/>\n    </shape>\n</scene>\n", 6, None, "no-such.obj"),
    ("undeclared parameter use", GOOD_HEAD + "    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"$r\"/>\n    </shape>\n</scene>\n", 6, None, "r"),
]


@pytest.mark.parametrize("name, text, line, column, words", CASES, ids=[c[0] for c in CASES])
def test_scene_errors_are_located(tmp_path, name, text, line, column, words):
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(snell.SceneError) as info:
        snell.load_file(path)
    e = info.value
    assert isinstance(e, ValueError)
    assert e.file == str(path)
    assert e.line == line, str(e)
    assert e.column is not None and e.column >= 1
    if column is not None:
        assert e.column == column, str(e)
    assert words in str(e)
    assert f"{path}:{e.line}:{e.column}" in str(e)
    # The message is the command line's, word for word.
    cli = subprocess.run([snell_command(), "render", str(path), "-o", str(tmp_path / "x.exr")],
                         capture_output=True, text=True, timeout=60)
    assert cli.returncode == 1
    assert cli.stderr.strip() == str(e).strip()
    # load_string locates the same way (in the name it is given)
    with pytest.raises(snell.SceneError) as again:
        snell.load_string(text, base=path)
    assert (again.value.file, again.value.line, again.value.column) == (e.file, e.line, e.column)


def test_unreadable_file_names_the_file(tmp_path):
    with pytest.raises(snell.SceneError) as info:
        snell.load_file(tmp_path / "missing.xml")
    assert info.value.file == str(tmp_path / "missing.xml")
    assert info.value.line is None and "cannot read scene file" in str(info.value)


def test_unknown_param_lists_the_declared_ones(cornell):
    with pytest.raises(snell.SceneError) as info:
        snell.load_file(cornell, resolution=4)
    assert info.value.file == cornell
    assert "resolution" in str(info.value) and "res" in info.value.help


def test_mode_the_scene_cannot_use_is_a_scene_error(tmp_path):
    path = tmp_path / "pt.xml"
    path.write_text(GOOD_HEAD.replace("<sensor", "<integrator type=\"ptracer\"/>\n    <sensor")
                    + "    <shape type=\"sphere\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"1\"/></emitter></shape>\n</scene>\n")
    scene = snell.load_file(path)
    with pytest.raises(snell.SceneError, match="polarized") as info:
        snell.render(scene, spp=1, mode="rgb-polarized")
    assert info.value.file == str(path)


def test_bad_dicts_raise_scene_errors():
    with pytest.raises(snell.SceneError, match="type"):
        snell.load_dict({"sphere": {"type": "sphere"}})
    with pytest.raises(snell.SceneError, match="teapot"):
        snell.load_dict({"type": "scene", "s": {"type": "teapot"}})
    with pytest.raises(snell.SceneError, match="cannot express"):
        snell.load_dict({"type": "scene", "s": {"type": "sphere", "radius": object()}})
    # an error the loader finds points into the generated XML
    d = {"type": "scene", "s": {"type": "sphere", "radius": "big"}}
    with pytest.raises(snell.SceneError) as info:
        snell.load_dict(d)
    xml_lines = snell.dict_to_xml(d).splitlines()
    assert info.value.line is not None
    assert "radius" in xml_lines[info.value.line - 1]
