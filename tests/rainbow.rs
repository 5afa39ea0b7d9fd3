//! The rainbow: light refracted into a drop of water, reflected inside it
//! once (primary bow) or twice (secondary), and refracted out, leaves most
//! concentrated at the angle of minimum deviation D_min, which depends on
//! the wavelength through the water's index n(λ).
//!
//! Descartes' closed form: a ray with incidence i and refraction angle r
//! (sin i = n sin r) that is reflected k times inside the drop is deviated
//! by D = k·180° + 2i − 2(k+1)r. D is stationary where
//! cos² i = (n² − 1) / (k² + 2k): (n² − 1)/3 for the primary, (n² − 1)/8 for
//! the secondary. The bow is seen at 180° − D_min (primary) and
//! D_min − 180° (secondary) from the antisolar point.
//!
//! What is rendered, and why not the sky. In the sky (`scenes/rainbow.xml`)
//! a camera path has to leave a drop inside the sun's 0.53° disk: with the
//! internal reflection's Fresnel factor that is a chance of about 1e-5 per
//! sample at the primary bow and 1e-6 at the secondary, so a path-traced
//! angular profile needs ~1e9 samples. A light path cannot be connected to
//! a pinhole through the drop's delta surfaces either. The tests therefore
//! repeat Descartes' own experiment (`scenes/rainbow-descartes.xml`):
//! one drop in a narrow beam throws the bows back onto a white screen around
//! the beam, where particle tracing lands every light path that leaves the
//! drop. The physics tested is the same (the drop's deviation, Fresnel
//! weights, dispersion); only the detector differs.
//!
//! Per wavelength, not per channel: a display channel integrates a band of
//! wavelengths (the red one sees 573–636 nm at half its peak), so its bow
//! is a blend of bows 0.3° apart. The peak angle of one wavelength λ is
//! measured directly by rendering a drop of constant index n(λ): exactly
//! what spectral mode computes for a path whose hero wavelength is λ once
//! it has crossed the dispersive surface (the other wavelengths are dropped
//! there). A spectral render with dispersive water then checks the colours:
//! each channel's bows within the Descartes angles of its band.
//!
//! Each pixel's angle from the antisolar direction is the angle at the drop
//! between the beam's source and the screen point the pixel sees. Its
//! uncertainty: the beam's directions differ by up to 0.143° across the drop
//! (the drop as seen from the point source), a ray leaving the drop off its
//! centre lands up to 0.06° off (drop radius / screen distance), and a
//! 0.1° bin is ±0.05° wide: ±0.25° in all, against 1.9° between the red and
//! violet primary bows. With the real sun the bows are also blurred by its
//! 0.53° disk (±0.27°); the point source leaves them sharp, so the peaks can
//! be measured to the tolerance above.

use crate::common::*;
use glam::Vec2;
use snell::bsdf::dispersion::named_dispersive;
use snell::emitter::Emitter;
use snell::film::Image;
use snell::spectrum::Rgb;
use snell::spectrum::cie::{cie_xyz, d65, xyz_to_linear_srgb};
use snell::spectrum::sampled::Sampled;

/// Bins of the angular profile (degrees from the antisolar point).
const BIN: f64 = 0.1;
const FIRST: f64 = 28.0;
const BINS: usize = 300;
/// The tolerance of a measured peak angle (see the module documentation).
const TOL: f64 = 0.25;

/// The rainbow angle (degrees from the antisolar point) of a drop of
/// relative index `n` after `k` internal reflections (1 or 2), closed form.
fn descartes(n: f64, k: u32) -> f64 {
    let k = k as f64;
    let cos_i = ((n * n - 1.0) / (k * k + 2.0 * k)).sqrt();
    let i = cos_i.acos();
    let r = (i.sin() / n).asin();
    let d = (k * 180.0 + 2.0 * i.to_degrees() - 2.0 * (k + 1.0) * r.to_degrees()).rem_euclid(360.0);
    if k == 1.0 { 180.0 - d } else { d - 180.0 }
}

/// The same by brute force: the extreme over impact parameters b of the
/// angle from the antisolar point, 180° − D(b) with
/// D(b) = k·180° + 2 asin b − 2(k+1) asin(b/n) folded to [0°, 180°]; the
/// primary's angles reach up to its bow, the secondary's down to its bow.
fn descartes_numeric(n: f64, k: u32) -> f64 {
    let kf = k as f64;
    let (mut lowest, mut highest) = (f64::MAX, f64::MIN);
    for step in 1..2_000_000 {
        let b = step as f64 / 2_000_000.0;
        let d = (kf * 180.0 + 2.0 * b.asin().to_degrees() - 2.0 * (kf + 1.0) * (b / n).asin().to_degrees()).rem_euclid(360.0);
        let angle = 180.0 - if d > 180.0 { 360.0 - d } else { d };
        lowest = lowest.min(angle);
        highest = highest.max(angle);
    }
    if k == 1 { highest } else { lowest }
}

/// Water's index relative to the air around the drop, at `lambda` nm.
fn water(lambda: f32) -> f64 {
    let water = named_dispersive("water").expect("water");
    let air = snell::bsdf::ior::lookup_ior("air").expect("air");
    water.eval(lambda) as f64 / air as f64
}

#[test]
fn descartes_angles_of_snells_water() {
    for k in [1, 2] {
        for lambda in [400.0f32, 550.0, 700.0] {
            let (closed, numeric) = (descartes(water(lambda), k), descartes_numeric(water(lambda), k));
            assert!(
                (closed - numeric).abs() < 1e-3,
                "k = {k}, {lambda} nm: closed form {closed}°, minimum of D(b) {numeric}°"
            );
        }
    }
    let (red, violet) = (descartes(water(680.0), 1), descartes(water(400.0), 1));
    eprintln!("primary: {red:.3}° (680 nm) to {violet:.3}° (400 nm)");
    assert!((red - 42.4).abs() < 0.05 && (violet - 40.6).abs() < 0.05, "{red} {violet}");
    let (red2, violet2) = (descartes(water(680.0), 2), descartes(water(400.0), 2));
    eprintln!("secondary: {red2:.3}° (680 nm) to {violet2:.3}° (400 nm)");
    assert!(50.0 < red2 && red2 < violet2 && violet2 < 54.0, "{red2} {violet2}");
    // Alexander's band: no light of either order between the bows.
    assert!(red + 7.0 < red2);
}

/// Renders the Descartes scene and bins its channels by the angle of each
/// pixel from the antisolar direction. Returns the mean of each channel per bin.
fn profile<S: snell::spectrum::Spectrum>(ior: &str, res: u32, spp: u32) -> Vec<[f64; 3]> {
    let path = repo("scenes/rainbow-descartes.xml");
    let res = res.to_string();
    let options = snell::LoadOptions {
        params: params(&[("ior", ior), ("res", &res)]),
        spp: Some(spp),
        seed: Some(5),
    };
    let scene = snell::load_file(&path, &options).unwrap_or_else(|e| panic!("{e}"));
    let start = std::time::Instant::now();
    let image: Image = snell::render::<S>(&scene, &snell::RenderOptions::default()).expect("render").0;
    eprintln!("rendered ior {ior} in {:.1} s", start.elapsed().as_secs_f64());
    let sun = scene
        .emitters
        .iter()
        .find_map(|e| if let Emitter::Spot(s) = e { Some(s.position) } else { None })
        .expect("the beam's spot light");
    // The drop sits at the origin; the direction to the sun is the beam's axis reversed.
    let to_sun = sun.normalize();
    let mut sum = vec![[0.0f64; 3]; BINS];
    let mut count = vec![0u32; BINS];
    for y in 0..image.height {
        for x in 0..image.width {
            let film = Vec2::new((x as f32 + 0.5) / image.width as f32, (y as f32 + 0.5) / image.height as f32);
            let Some(hit) = scene.intersect(&scene.camera.generate_ray(film)) else {
                continue;
            };
            let angle = (hit.p.normalize().dot(to_sun) as f64).clamp(-1.0, 1.0).acos().to_degrees();
            let bin = ((angle - FIRST) / BIN).floor();
            if bin >= 0.0 && (bin as usize) < BINS {
                let p: Rgb = image.pixels[(y * image.width + x) as usize];
                for c in 0..3 {
                    sum[bin as usize][c] += p[c] as f64;
                }
                count[bin as usize] += 1;
            }
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &n)| s.map(|v| if n > 0 { v / n as f64 } else { 0.0 }))
        .collect()
}

fn angle_of(bin: usize) -> f64 {
    FIRST + (bin as f64 + 0.5) * BIN
}

/// The centre of the brightest bin of `value` between `lo` and `hi` degrees.
fn peak(profile: &[[f64; 3]], lo: f64, hi: f64, value: impl Fn(&[f64; 3]) -> f64) -> f64 {
    let bins = (0..profile.len()).filter(|&b| angle_of(b) > lo && angle_of(b) < hi);
    let best = bins
        .max_by(|&a, &b| value(&profile[a]).total_cmp(&value(&profile[b])))
        .expect("bins in range");
    angle_of(best)
}

fn mean_over(profile: &[[f64; 3]], lo: f64, hi: f64, value: impl Fn(&[f64; 3]) -> f64) -> f64 {
    let v: Vec<f64> = (0..profile.len())
        .filter(|&b| angle_of(b) > lo && angle_of(b) < hi)
        .map(|b| value(&profile[b]))
        .collect();
    v.iter().sum::<f64>() / v.len() as f64
}

fn luminance(p: &[f64; 3]) -> f64 {
    (p[0] + p[1] + p[2]) / 3.0
}

/// One wavelength at a time: a drop of water's index at λ (a constant, in
/// RGB mode: what spectral mode computes for a path whose hero wavelength is
/// λ) puts both bows where Descartes' minimum deviation says.
#[test]
fn each_wavelength_bows_at_its_minimum_deviation() {
    let mut primaries = Vec::new();
    let mut secondaries = Vec::new();
    for lambda in [450.0f32, 550.0, 650.0] {
        let water_abs = named_dispersive("water").expect("water").eval(lambda);
        let ior = format!("cauchy({water_abs}, 0)");
        let prof = profile::<Rgb>(&ior, 384, 8);
        let n = water(lambda);
        let (want1, want2) = (descartes(n, 1), descartes(n, 2));
        let (got1, got2) = (peak(&prof, 38.0, 45.0, luminance), peak(&prof, 49.0, 56.0, luminance));
        eprintln!("{lambda} nm (n = {n:.5}): primary {got1:.2}° (Descartes {want1:.3}°), secondary {got2:.2}° (Descartes {want2:.3}°)");
        assert!(
            (got1 - want1).abs() < TOL,
            "{lambda} nm: primary bow at {got1}°, Descartes says {want1}°"
        );
        assert!(
            (got2 - want2).abs() < TOL,
            "{lambda} nm: secondary bow at {got2}°, Descartes says {want2}°"
        );
        // Alexander's dark band: only the drop's outer reflection lights it.
        let band = mean_over(&prof, want1 + 0.5, want2 - 0.5, luminance);
        let inside = mean_over(&prof, 30.0, want1 - 3.0, luminance);
        assert!(
            band < 0.2 * inside,
            "{lambda} nm: Alexander's band {band} vs inside the bow {inside}"
        );
        primaries.push(got1);
        secondaries.push(got2);
    }
    // Red outside violet in the primary, inside it in the secondary.
    assert!(primaries[0] < primaries[1] && primaries[1] < primaries[2], "{primaries:?}");
    assert!(
        secondaries[0] > secondaries[1] && secondaries[1] > secondaries[2],
        "{secondaries:?}"
    );
}

/// The wavelengths a display channel mainly sees: where its colour-matching
/// response (CIE → linear sRGB) to the white beam (D65) is at least half its
/// maximum.
fn channel_band(c: usize) -> (f32, f32) {
    let weight = |lambda: f32| xyz_to_linear_srgb(cie_xyz(lambda))[c] * d65(lambda);
    let lambdas: Vec<f32> = (0..=350).map(|i| 380.0 + i as f32).collect();
    let max = lambdas.iter().map(|&l| weight(l)).fold(0.0f32, f32::max);
    let inside: Vec<f32> = lambdas.iter().copied().filter(|&l| weight(l) >= 0.5 * max).collect();
    (inside[0], inside[inside.len() - 1])
}

/// All wavelengths at once: dispersive water in spectral mode splits the
/// white beam; each colour channel's bow lies where Descartes puts the
/// wavelengths that channel sees, red outside in the primary and inside in
/// the secondary, with Alexander's dark band between.
#[test]
fn dispersive_drop_makes_a_coloured_double_rainbow() {
    let prof = profile::<Sampled>("sellmeier:water", 384, 16);
    let mut primary = [0.0; 3];
    let mut secondary = [0.0; 3];
    for c in 0..3 {
        let channel = |p: &[f64; 3]| p[c];
        primary[c] = peak(&prof, 38.0, 45.0, channel);
        secondary[c] = peak(&prof, 49.0, 56.0, channel);
        let (short, long) = channel_band(c);
        // Longer waves are bent less: their primary bow is further out.
        let (lo1, hi1) = (descartes(water(short), 1), descartes(water(long), 1));
        let (lo2, hi2) = (descartes(water(long), 2), descartes(water(short), 2));
        eprintln!(
            "channel {c} ({short}–{long} nm): primary {:.2}° (Descartes {lo1:.2}°–{hi1:.2}°), secondary {:.2}° ({lo2:.2}°–{hi2:.2}°)",
            primary[c], secondary[c]
        );
        assert!(
            primary[c] > lo1 - TOL && primary[c] < hi1 + TOL,
            "channel {c}: primary at {}°",
            primary[c]
        );
        assert!(
            secondary[c] > lo2 - TOL && secondary[c] < hi2 + TOL,
            "channel {c}: secondary at {}°",
            secondary[c]
        );
    }
    // (b) red outside blue in the primary, inside it in the secondary.
    assert!(primary[0] > primary[2] + 0.4, "primary: red {}°, blue {}°", primary[0], primary[2]);
    assert!(
        secondary[0] + 0.4 < secondary[2],
        "secondary: red {}°, blue {}°",
        secondary[0],
        secondary[2]
    );
    // (c) the secondary bow between 50° and 54°.
    let second = peak(&prof, 46.0, 58.0, luminance);
    assert!((50.0..54.0).contains(&second), "secondary bow at {second}°");
    // (d) Alexander's band darker than the sky inside the primary.
    let band = mean_over(&prof, 43.0, 49.8, luminance);
    let inside = mean_over(&prof, 30.0, 39.0, luminance);
    eprintln!("Alexander's band {band:.4}, inside the primary {inside:.4}");
    assert!(band < 0.2 * inside, "Alexander's band {band} vs inside {inside}");
}
