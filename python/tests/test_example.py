"""examples/snells_window.py: Snell's window against its closed form
F(θ) + (1 − F(θ)) η² inside the critical angle, 1 outside."""

import importlib.util

import numpy as np

from conftest import ROOT


def test_snells_window_matches_the_closed_form():
    spec = importlib.util.spec_from_file_location("snells_window", ROOT / "examples" / "snells_window.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    _, _, centres, means, exact, critical = example.measure(spp=16)
    assert abs(critical - 48.6) < 0.05
    away = np.abs(centres - critical) > 2.0
    # binned means of ~100+ pixels × 16 spp: noise well under 2 %
    assert np.max(np.abs(means[away] - exact[away]) / exact[away]) < 0.02
    inside, outside = centres < critical - 2, centres > critical + 2
    assert inside.sum() > 10 and outside.sum() > 10
    assert np.all(means[inside] > 1.3)
    assert np.allclose(means[outside], 1.0, atol=1e-3)
