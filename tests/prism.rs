//! The rendered prism: `scenes/prism.xml` (a narrow white beam through a 60°
//! SF11 prism onto a screen), rendered in spectral mode, must spread its
//! colours where Snell's law puts each wavelength.
//!
//! The expected image position of each wavelength comes from tracing the
//! beam's axis through the scene's prism with Snell's law written here (the
//! index from the SF11 Sellmeier formula) and projecting the screen hit with
//! the camera. Each image channel is a linear functional of the spectrum, so
//! its intensity-weighted column centroid is predicted exactly by weighting
//! those positions with D65 (the white beam's spectrum), the Fresnel
//! transmittance of both faces and the channel's colour-matching response.

use crate::common::*;
use glam::Vec3;
use snell::bsdf::dispersion::named_dispersive;
use snell::bsdf::fresnel::fresnel_dielectric;
use snell::emitter::Emitter;
use snell::geometry::Ray;
use snell::sensor::Camera;
use snell::spectrum::cie::{cie_xyz, d65, xyz_to_linear_srgb};
use snell::spectrum::sampled::Sampled;

const RES: u32 = 128;

/// Refracts unit `d` through a surface with unit normal `n` (either side)
/// from index `n1` into `n2`; also returns the Fresnel transmittance.
fn refract(d: Vec3, n: Vec3, n1: f32, n2: f32) -> (Vec3, f32) {
    let n = if d.dot(n) < 0.0 { n } else { -n };
    let cos_i = -d.dot(n);
    let r = n1 / n2;
    let cos_t = (1.0 - r * r * (1.0 - cos_i * cos_i)).sqrt();
    assert!(cos_t.is_finite(), "total internal reflection on the beam's axis");
    let t = 1.0 - fresnel_dielectric(cos_i, n2 / n1).r;
    ((d * r + n * (r * cos_i - cos_t)).normalize(), t)
}

/// Film column (pixels) where the beam's axis lands for a glass of index
/// `n_glass`, the fraction that crosses both faces, and the deviation angle
/// (radians). `None` if it misses the prism, the screen or the film.
fn landing_and_deviation(scene: &snell::Scene, n_glass: f32) -> Option<(f32, f32, f32)> {
    let spot = spot(scene);
    trace_beam_ray(scene, spot.position, spot.axis, n_glass)
}

fn spot(scene: &snell::Scene) -> snell::emitter::SpotLight {
    // The beam is the narrow spot (the other one is the fill light).
    scene.emitters.iter().find_map(|e| if let Emitter::Spot(s) = e { (s.cutoff < 0.1).then(|| s.clone()) } else { None }).expect("a narrow spot light")
}

fn trace_beam_ray(scene: &snell::Scene, origin: Vec3, dir: Vec3, n_glass: f32) -> Option<(f32, f32, f32)> {
    let Camera::Perspective(camera) = &scene.camera else { return None };
    let entry = scene.intersect(&Ray::new(origin, dir))?;
    // The scene's glass sits in air (ext_ior "air" = 1.000277), not vacuum:
    // that alone moves the beam by a third of a pixel here.
    let air = snell::bsdf::ior::lookup_ior("air").expect("air");
    let (d1, t1) = refract(dir, entry.n, air, n_glass);
    let exit = scene.intersect(&Ray::new(entry.p + d1 * 1e-4, d1))?;
    let (d2, t2) = refract(d1, exit.n, n_glass, air);
    let screen = scene.intersect(&Ray::new(exit.p + d2 * 1e-4, d2))?;
    let c = camera.connect(screen.p, scene.film.width, scene.film.height)?;
    Some((c.film.x * scene.film.width as f32, t1 * t2, dir.dot(d2).clamp(-1.0, 1.0).acos()))
}

/// The whole beam, not just its axis: the spot's cone on a grid of equal
/// solid angles, each ray weighted by the spot's falloff and its Fresnel
/// transmittance. Returns Σw·x and Σw for a glass of index `n_glass`.
fn beam_moments(scene: &snell::Scene, n_glass: f32) -> (f64, f64) {
    let spot = spot(scene);
    let frame = snell::math::Frame::from_normal(spot.axis);
    let (rings, arms) = (12, 24);
    let (mut moment, mut sum) = (0.0f64, 0.0f64);
    for i in 0..rings {
        let cos_t = 1.0 - (i as f32 + 0.5) / rings as f32 * (1.0 - spot.cos_cutoff);
        let sin_t = (1.0 - cos_t * cos_t).sqrt();
        for j in 0..arms {
            let phi = std::f32::consts::TAU * (j as f32 + 0.5) / arms as f32;
            let dir = frame.to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t));
            let w = spot.falloff(dir);
            if w <= 0.0 {
                continue;
            }
            if let Some((x, t, _)) = trace_beam_ray(scene, spot.position, dir, n_glass) {
                moment += (w * t * x) as f64;
                sum += (w * t) as f64;
            }
        }
    }
    (moment, sum)
}

/// Intensity-weighted mean column of each channel (pixel centres at i + ½).
fn centroids(img: &snell::film::Image) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    let mut moment = [0.0f64; 3];
    for (i, p) in img.pixels.iter().enumerate() {
        let x = (i as u32 % img.width) as f64 + 0.5;
        for c in 0..3 {
            sum[c] += p[c] as f64;
            moment[c] += x * p[c] as f64;
        }
    }
    [0, 1, 2].map(|c| moment[c] / sum[c])
}

fn expected_centroids(scene: &snell::Scene, index: impl Fn(f32) -> f32) -> [f64; 3] {
    let mut sum = [0.0f64; 3];
    let mut moment = [0.0f64; 3];
    for step in 0..=235 {
        let lambda = 360.0 + 2.0 * step as f32;
        let (m, s) = beam_moments(scene, index(lambda));
        let rgb = xyz_to_linear_srgb(cie_xyz(lambda));
        // The beam's spectrum: white RGB intensity as spectral mode emits it
        // (D65 times the uplifted white, which is flat to about 1e-3).
        let wl = snell::spectrum::sampled::Wavelengths { lambda: [lambda; 4], pdf: [1.0; 4] };
        let emitted = <Sampled as snell::spectrum::Spectrum>::from_illuminant(snell::spectrum::Rgb::WHITE, &wl).0.x / d65(lambda);
        for c in 0..3 {
            let w = (d65(lambda) * emitted * rgb[c]) as f64;
            sum[c] += w * s;
            moment[c] += w * m;
        }
    }
    [0, 1, 2].map(|c| moment[c] / sum[c])
}

fn render(params_: &[(&str, &str)]) -> (snell::Scene, snell::film::Image) {
    let path = repo("scenes/prism.xml");
    // max_depth 4 = spot → entry face → exit face → screen → camera: the
    // beam itself. Longer paths add light reflected inside the prism (more of
    // it in the violet, nearer total internal reflection), which lands
    // elsewhere and moves the blue centroid by 0.2 px.
    let mut list = vec![("res", "128"), ("fill", "0"), ("max_depth", "4")];
    list.extend_from_slice(params_);
    let options = snell::LoadOptions { params: params(&list), spp: Some(48), seed: Some(3) };
    let scene = snell::load_file(&path, &options).unwrap_or_else(|e| panic!("{e}"));
    let image = snell::render::<Sampled>(&scene, &snell::RenderOptions::default()).expect("render").0;
    (scene, image)
}

#[test]
fn prism_spreads_the_spectrum_where_snells_law_puts_it() {
    let (scene, image) = render(&[]);
    assert_eq!(image.width, RES);
    let sf11 = named_dispersive("sf11").expect("sf11");
    let got = centroids(&image);
    let want = expected_centroids(&scene, |l| sf11.eval(l));
    eprintln!("prism centroids (px): rendered R {:.2} G {:.2} B {:.2}; Snell's law R {:.2} G {:.2} B {:.2}", got[0], got[1], got[2], want[0], want[1], want[2]);
    // Blue is bent more than red: on this film it lands further left.
    assert!(want[2] < want[1] && want[1] < want[0] && want[0] - want[2] > 10.0, "{want:?}");
    for c in 0..3 {
        assert!((got[c] - want[c]).abs() < 0.1, "channel {c}: centroid {:.2} px, Snell's law says {:.2} px", got[c], want[c]);
    }
    // The scene aims the beam at minimum deviation for the d line (587.6 nm):
    // the closed form δ_min = 2 asin(n_d sin 30°) − 60°. The F (486.1 nm) and
    // C (656.3 nm) lines then meet the same incidence θ₁ and leave at
    // δ = θ₁ + asin(n sin(60° − asin(sin θ₁ / n))) − 60°.
    let air = snell::bsdf::ior::lookup_ior("air").unwrap();
    let n_d = sf11.eval(587.56);
    // The beam was aimed (tools/gen_prism.py) for n_d in vacuum; in air the
    // relative index n_d / n_air is a hair lower, its minimum deviation too.
    let theta1 = (n_d * 0.5).asin();
    let (_, _, dev_d) = landing_and_deviation(&scene, n_d).unwrap();
    let closed_min = 2.0 * (n_d / air * 0.5).asin() - 60f32.to_radians();
    assert!((dev_d - closed_min).abs() < 2e-5, "d line: {} vs minimum deviation {}", dev_d.to_degrees(), closed_min.to_degrees());
    for lambda in [486.13f32, 656.27] {
        let n = sf11.eval(lambda) / air;
        let closed = theta1 + (n * (60f32.to_radians() - (theta1.sin() / n).asin()).sin()).asin() - 60f32.to_radians();
        let (_, _, dev) = landing_and_deviation(&scene, n * air).unwrap();
        eprintln!("{lambda} nm: n {n:.5}, deviation {:.4}° (closed form {:.4}°)", dev.to_degrees(), closed.to_degrees());
        assert!((dev - closed).abs() < 2e-4, "{lambda} nm: {} vs {}", dev.to_degrees(), closed.to_degrees());
    }
}

/// The control: the same beam through a non-dispersive glass of SF11's
/// d-line index lands in one place for every colour.
#[test]
fn constant_index_keeps_the_beam_white() {
    let (scene, image) = render(&[("glass", "cauchy(1.78472, 0)")]);
    let got = centroids(&image);
    let want = expected_centroids(&scene, |_| 1.78472);
    let (m, w) = beam_moments(&scene, 1.78472);
    let (axis, _, _) = landing_and_deviation(&scene, 1.78472).unwrap();
    eprintln!("beam centroid {:.2} px, its axis {:.2} px", m / w, axis);
    eprintln!("constant-index centroids (px): R {:.2} G {:.2} B {:.2}; expected {:.2}", got[0], got[1], got[2], want[1]);
    for c in 0..3 {
        assert!((got[c] - want[1]).abs() < 0.1, "channel {c}: {:.2} vs {:.2}", got[c], want[1]);
    }
}
