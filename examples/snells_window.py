"""Snell's window from Python: the brightness seen looking up from under a
flat water surface, against the angle from the vertical, beside the closed
form; and the gallery's scenes/snells-window.xml.

A camera under water looks straight up through a flat surface (η = 1.333)
at a uniform sky of radiance 1. A ray leaving the camera at angle θ from the
vertical is reflected back into the water with the Fresnel reflectance F(θ)
(where it meets the sky's light that entered elsewhere: radiance 1, the
scene being uniform) and refracted into the air with 1 − F(θ), where the sky
of radiance 1 looks η² brighter from inside the denser water:

    L(θ) = F(θ) + (1 − F(θ)) η²,    and L = 1 beyond the critical angle
    θ_c = asin(1/η) = 48.6° (total internal reflection).

The scene is built with ``snell.load_dict`` (Mitsuba's dictionary form).

    pip install ./python matplotlib
    python examples/snells_window.py            # writes snells_window.png
"""

import math
import os
import sys

import numpy as np

import snell

ETA = 1.333
FOV = 130.0  # degrees, across the image (x)
RES = 128


def fresnel(cos_i: float, eta: float) -> float:
    """Unpolarized Fresnel reflectance at a dielectric interface for a ray
    arriving at cos_i, going into a medium of relative index eta."""
    sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin_t2 >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin_t2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs * rs + rp * rp)


def closed_form(theta_deg: np.ndarray) -> np.ndarray:
    out = []
    for t in np.radians(theta_deg):
        f = fresnel(math.cos(t), 1.0 / ETA)  # from the water into the air
        out.append(f + (1.0 - f) * ETA * ETA)
    return np.array(out)


def window_scene(spp: int) -> snell.Scene:
    return snell.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": -1},
            "sensor": {
                "type": "perspective",
                "fov": FOV,
                "fov_axis": "x",
                # one metre under the surface, looking up (+z)
                "to_world": snell.ScalarTransform4f().look_at(origin=[0, 0, -1], target=[0, 0, 0], up=[0, 1, 0]),
                "sampler": {"type": "independent", "sample_count": spp},
                "film": {"type": "hdrfilm", "width": RES, "height": RES, "rfilter": {"type": "box"}},
            },
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
            # the surface faces +z: water (1.333) below, air above
            "surface": {
                "type": "rectangle",
                "to_world": snell.ScalarTransform4f().scale(50),
                "bsdf": {"type": "dielectric", "int_ior": ETA, "ext_ior": 1.0},
            },
        }
    )


def pixel_angles(res: int, fov_deg: float) -> np.ndarray:
    """Angle from the vertical (the view axis) of each pixel centre's ray."""
    tan_half = math.tan(math.radians(fov_deg) / 2)
    c = (np.arange(res) + 0.5) / res * 2 - 1  # -1 .. 1 across the film
    x, y = np.meshgrid(c * tan_half, c * tan_half)
    return np.degrees(np.arctan(np.hypot(x, y)))


def measure(spp: int):
    """Renders the window; returns the image's brightness, the binned
    (angle, mean brightness) pairs, the closed form at those angles, and the
    critical angle."""
    scene = window_scene(spp)
    image = snell.render(scene, spp=spp)
    brightness = image[..., 1]  # the sky is grey: G = R = B
    theta = pixel_angles(RES, FOV)
    bins = np.linspace(0, theta.max(), 60)
    idx = np.digitize(theta.ravel(), bins)
    centres, means = [], []
    for k in range(1, len(bins)):
        sel = idx == k
        if sel.any():
            centres.append(theta.ravel()[sel].mean())
            means.append(brightness.ravel()[sel].mean())
    centres, means = np.array(centres), np.array(means)
    return brightness, theta, centres, means, closed_form(centres), math.degrees(math.asin(1 / ETA))


def main(out: str = "snells_window.png", spp: int = 64) -> None:
    brightness, theta, centres, means, exact, critical = measure(spp)
    # Away from the window's edge (where a bin mixes the two sides), the
    # render and the closed form agree to within the noise.
    away = np.abs(centres - critical) > 2.0
    worst = np.max(np.abs(means[away] - exact[away]) / exact[away])
    print(f"critical angle {critical:.2f}°; largest deviation from the closed form away from the edge: {100 * worst:.2f} %")

    gallery = snell.render(snell.load_file(os.path.join(os.path.dirname(__file__), "..", "scenes", "snells-window.xml"), res=160), spp=32)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
    ax[0].imshow(np.clip(brightness / (ETA * ETA), 0, 1) ** (1 / 2.2), cmap="gray", vmin=0, vmax=1)
    ax[0].set_title("looking up from under water (uniform sky)")
    ax[0].axis("off")
    t = np.linspace(0, theta.max(), 400)
    ax[1].plot(t, closed_form(t), "k-", lw=1, label="closed form F + (1 − F) η²")
    ax[1].plot(centres, means, "o", ms=3, color="tab:blue", label=f"Snell ({spp} spp)")
    ax[1].axvline(critical, color="tab:red", lw=0.8, ls="--", label=f"critical angle {critical:.1f}°")
    ax[1].set_xlabel("angle from the vertical (degrees)")
    ax[1].set_ylabel("radiance (sky = 1)")
    ax[1].legend(loc="lower left", fontsize=8)
    ax[1].set_title("brightness against angle")
    ax[2].imshow(np.clip(gallery, 0, 1) ** (1 / 2.2))
    ax[2].set_title("scenes/snells-window.xml")
    ax[2].axis("off")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:2])
