"""Rendering through Python: bit-identical to the command line, parameters,
polarized channels, progress, image files, introspection."""

import subprocess

import numpy as np
import pytest

import snell
from conftest import SCENES, TEST_SCENES, commands, snell_command


@pytest.mark.parametrize(
    "scene, mode, spp, seed, params",
    [
        (SCENES / "cornell-box.xml", "rgb", 8, 3, {"res": "24"}),
        (SCENES / "cornell-box.xml", "spectral", 4, 0, {"res": "16"}),
        (TEST_SCENES / "polarized-glass-metal.xml", "rgb-polarized", 4, 7, {"res": "16"}),
        (TEST_SCENES / "aov.xml", "rgb", 2, 1, {}),
    ],
)
def test_render_is_bit_identical_to_the_command_line(tmp_path, scene, mode, spp, seed, params):
    s = snell.load_file(scene, **params)
    image = snell.render(s, spp=spp, seed=seed, mode=mode)
    assert image.dtype == np.float32
    assert image[..., :3].max() > 0
    defines = [a for k, v in params.items() for a in ("-D", f"{k}={v}")]
    for what, command in commands():
        out = tmp_path / f"{what}.exr"
        cmd = [command, "render", str(scene), "-o", str(out), "--spp", str(spp), "--seed", str(seed),
               "--mode", mode, "-q", *defines]
        subprocess.run(cmd, check=True, timeout=600)
        cli = snell.read(out)
        assert image.shape == cli.shape, (what, image.shape, cli.shape)
        assert snell.channel_names(s, mode) == snell.channel_names(out), what
        assert np.array_equal(image, cli), f"{what}: max difference {np.abs(image - cli).max()}"


def test_params_set_declared_defaults(cornell):
    s = snell.load_file(cornell, res=20, max_depth=3)
    assert s.size == (20, 20) and s.film_size == (20, 20)
    assert s.parameters == {"spp": "64", "res": "20", "max_depth": "3"}
    assert s.spp == 64
    assert snell.render(s, spp=1).shape == (20, 20, 3)
    # `spp` as a parameter and as the render's argument
    assert snell.load_file(cornell, res=8, spp=5).spp == 5


def test_seed_and_spp_arguments(cornell):
    s = snell.load_file(cornell, res=16)
    a = snell.render(s, spp=2, seed=1)
    b = snell.render(s, spp=2, seed=1)
    c = snell.render(s, spp=2, seed=2)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    # the scene's own sampler is untouched by a render's overrides
    assert s.spp == 64 and s.seed == 0


def test_polarized_channels(polarized_scene):
    s = snell.load_file(polarized_scene, res=16)
    names = snell.channel_names(s, "rgb-polarized")
    assert names[:3] == ["R", "G", "B"]
    assert names[3:] == [f"S{k}.{c}" for k in range(4) for c in "RGB"]
    img = snell.render(s, spp=8, mode="rgb-polarized")
    assert img.shape == (16, 16, 15)
    s0, s1, s2, s3 = (img[..., 3 + 3 * k: 6 + 3 * k] for k in range(4))
    assert np.array_equal(s0, img[..., :3])
    # a physical Stokes vector: the polarized part is no larger than the intensity
    dop = np.sqrt(s1 ** 2 + s2 ** 2 + s3 ** 2)
    assert np.all(dop <= s0 * (1 + 1e-4) + 1e-6)
    # the polarizer half of the view is strongly polarized, somewhere
    assert np.abs(s1).max() > 0.05
    # the unpolarized modes have no Stokes channels
    assert snell.render(s, spp=1).shape == (16, 16, 3)


def test_variant_sets_the_default_mode(polarized_scene):
    s = snell.load_file(polarized_scene, res=8)
    try:
        snell.set_variant("scalar_rgb_polarized")
        assert snell.render(s, spp=1).shape[2] == 15
    finally:
        snell.set_variant("scalar_rgb")
    with pytest.raises(ValueError, match="llvm_ad_rgb"):
        snell.set_variant("gpu_rgb")


def test_progress_reports_each_pass(cornell):
    s = snell.load_file(cornell, res=16)
    seen = []
    final = snell.render(s, spp=8, progress=lambda f, img: seen.append((f, img.copy())), passes=4)
    fractions = [f for f, _ in seen]
    assert len(seen) == 4
    assert fractions == sorted(fractions) and fractions[-1] == 1.0 and fractions[0] < 1.0
    assert all(img.shape == (16, 16, 3) for _, img in seen)
    assert np.array_equal(seen[-1][1], final)


def test_an_exception_in_progress_stops_the_render(cornell):
    s = snell.load_file(cornell, res=16)

    def stop(fraction, image):
        raise RuntimeError("enough")

    with pytest.raises(RuntimeError, match="enough"):
        snell.render(s, spp=64, progress=stop, passes=6)


def test_bad_render_arguments(cornell):
    s = snell.load_file(cornell, res=8)
    with pytest.raises(ValueError, match="rgb-polarized"):
        snell.render(s, mode="hyperspectral")
    with pytest.raises(ValueError, match="2\\^24"):
        snell.render(s, spp=1 << 25)
    with pytest.raises(ValueError, match="4096"):
        snell.render(s, threads=100000)
    with pytest.raises(TypeError):
        snell.render("scene.xml")


def test_write_and_read_round_trip(tmp_path, polarized_scene):
    s = snell.load_file(polarized_scene, res=8)
    img = snell.render(s, spp=2, mode="rgb-polarized")
    names = snell.channel_names(s, "rgb-polarized")
    snell.write(img, tmp_path / "a.exr", channels=names)
    assert np.array_equal(snell.read(tmp_path / "a.exr"), img)
    assert snell.channel_names(tmp_path / "a.exr") == names
    rgb = img[..., :3]
    snell.write(rgb, tmp_path / "a.pfm")
    assert np.array_equal(snell.read(tmp_path / "a.pfm"), rgb)
    snell.write(rgb, tmp_path / "a.png")
    png = snell.read(tmp_path / "a.png")
    assert png.shape == (8, 8, 3) and 0 <= png.min() and png.max() <= 1
    with pytest.raises(ValueError, match="names"):
        snell.write(np.zeros((4, 4, 5)), tmp_path / "b.exr")
    with pytest.raises(OSError):
        snell.write(rgb, tmp_path / "no-such-folder" / "c.exr")
    with pytest.raises(OSError):
        snell.read(tmp_path / "missing.exr")


def test_introspection(cornell):
    s = snell.load_file(cornell, res=32)
    sensors = s.sensors()
    assert len(sensors) == 1 and sensors[0]["type"] == "perspective"
    assert sensors[0]["film"]["size"] == (32, 32)
    assert sensors[0]["sampler"]["sample_count"] == 64
    assert s.emitters() == [{"type": "area"}]
    shapes = s.shapes()
    assert len(shapes) == 8 and sum(sh["emitter"] for sh in shapes) == 1
    assert all(sh["type"] == "mesh" and sh["bsdf"] == "diffuse" for sh in shapes)
    assert s.integrator == "path"
    assert "cornell-box.xml" in repr(s)


def test_snell_command_is_installed(tmp_path):
    out = subprocess.run([snell_command(), "--version"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.startswith("snell ")
    bad = subprocess.run([snell_command(), "render", str(tmp_path / "none.xml")], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 1 and "cannot read scene file" in bad.stderr
