//! Shared helpers for image tests: render a scene in independent passes and
//! compare it with a reference (Mitsuba's image, or a closed form) block by
//! block, separating bias from noise.
#![allow(dead_code)]

use snell::film::Image;
use snell::spectrum::Rgb;
use snell::{LoadOptions, RenderOptions};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

pub fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

pub fn params(list: &[(&str, &str)]) -> HashMap<String, String> {
    list.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect()
}

/// The scene file's text with `extra` (property elements) added to its
/// `path` integrator block.
pub fn with_path_props(scene: &Path, extra: &str) -> String {
    let text = std::fs::read_to_string(scene).expect("scene");
    let anchor = r#"<integrator type="path">"#;
    assert!(text.contains(anchor), "{}: no path integrator", scene.display());
    text.replacen(anchor, &format!("{anchor}{extra}"), 1)
}

/// Renders `passes` independent images (seeds 1..=passes) of `spp` samples each.
pub fn render_passes(scene: &Path, text: Option<&str>, params: HashMap<String, String>, passes: u32, spp: u32) -> Vec<Image> {
    render_passes_as::<Rgb>(scene, text, params, passes, spp)
}

/// As [`render_passes`], with paths carrying the spectrum type `S`.
pub fn render_passes_as<S: snell::spectrum::Spectrum>(
    scene: &Path,
    text: Option<&str>,
    params: HashMap<String, String>,
    passes: u32,
    spp: u32,
) -> Vec<Image> {
    let options = LoadOptions { params, spp: Some(spp), seed: None };
    let mut scene = match text {
        Some(t) => snell::load_str(scene, t, &options),
        None => snell::load_file(scene, &options),
    }
    .unwrap_or_else(|e| panic!("{e}"));
    (1..=passes)
        .map(|seed| {
            scene.sampler.seed = seed as u64 * 7919;
            snell::render::<S>(&scene, &RenderOptions::default()).expect("render").0
        })
        .collect()
}

/// The image's pixel values as bits, for bit-for-bit comparisons.
pub fn pixel_bits(image: &Image) -> Vec<u32> {
    image.pixels.iter().flat_map(|p| p.0).map(f32::to_bits).collect()
}

/// Loads `text` (the scene at `path`) with `params`, renders it with one
/// thread in one pass, and asserts the same image, bit for bit, with 2
/// threads, 3 threads in 3 passes and 2 threads in 4 passes; returns it.
pub fn assert_exact_across_threads_and_passes(path: &Path, text: &str, params: HashMap<String, String>) -> Vec<u32> {
    let options = LoadOptions { params, ..Default::default() };
    let scene = snell::load_str(path, text, &options).unwrap_or_else(|e| panic!("{e}"));
    let render = |threads, passes| {
        let opts = RenderOptions { threads, passes, ..RenderOptions::default() };
        pixel_bits(&snell::render::render_passes::<Rgb>(&scene, &opts, &mut |_| {}).expect("render").0)
    };
    let want = render(1, 1);
    assert!(want.iter().filter(|&&b| f32::from_bits(b) > 0.0).count() > want.len() / 2, "mostly black");
    for (threads, passes) in [(2, 1), (3, 3), (2, 4)] {
        assert!(render(threads, passes) == want, "{threads} threads, {passes} passes differ");
    }
    want
}

/// The relMSE of each image against `reference`, summed over its pixels
/// and channels (denominator r² + 0.01), averaged over the images.
pub fn relmse_sum(images: &[Image], reference: &Image) -> f64 {
    let mut e = 0.0f64;
    for img in images {
        for (a, r) in img.pixels.iter().zip(&reference.pixels) {
            for c in 0..3 {
                e += ((a[c] - r[c]) as f64).powi(2) / ((r[c] as f64).powi(2) + 1e-2);
            }
        }
    }
    e / images.len() as f64
}

pub fn mean(img: &Image) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for p in &img.pixels {
        for c in 0..3 {
            m[c] += p[c] as f64;
        }
    }
    m.map(|v| v / img.pixels.len() as f64)
}

/// The pixel-wise mean of the images, and of their layers (Stokes S1–S3).
pub fn average(images: &[Image]) -> Image {
    let n = images.len() as f32;
    let mut out = images[0].clone();
    for (i, p) in out.pixels.iter_mut().enumerate() {
        let mut s = Rgb::BLACK;
        for img in images {
            s += img.pixels[i];
        }
        *p = s / n;
    }
    for (k, layer) in out.layers.iter_mut().enumerate() {
        for (i, p) in layer.pixels.iter_mut().enumerate() {
            let mut s = Rgb::BLACK;
            for img in images {
                s += img.layers[k].pixels[i];
            }
            *p = s / n;
        }
    }
    out
}

/// Layer `name` (e.g. "S1") of each image, as images of their own.
pub fn layer_images(images: &[Image], name: &str) -> Vec<Image> {
    images
        .iter()
        .map(|img| Image::new(img.width, img.height, img.layer(name).unwrap_or_else(|| panic!("no layer {name}")).pixels.clone()))
        .collect()
}

/// The seed's polarizing-filter photo as a test scene: a flat surface of
/// `surface_bsdf` (η 1.5; black below) reflects a white sky into a narrow
/// camera at Brewster's angle atan 1.5 = 56.3°, optionally through a
/// polarizer sheet at `polarizer_theta` degrees. The sheet faces the camera
/// with its ∂p/∂u horizontal (world x, the s direction), so θ = 0 passes
/// s-polarised light and θ = 90 blocks it.
pub fn brewster_scene(surface_bsdf: &str, polarizer_theta: Option<f32>) -> String {
    let brewster = 1.5f32.atan();
    let cam = glam::Vec3::new(0.0, brewster.cos(), brewster.sin()) * 5.0;
    let view = (-cam).normalize();
    let (at, to) = (cam + view, cam + 2.0 * view);
    let sheet = polarizer_theta.map_or(String::new(), |theta| {
        format!(
            r#"<shape type="rectangle">
        <transform name="to_world"><scale value="0.5"/><lookat origin="{}, {}, {}" target="{}, {}, {}" up="0, 1, 0"/></transform>
        <bsdf type="polarizer"><float name="theta" value="{theta}"/></bsdf>
    </shape>"#,
            at.x, at.y, at.z, to.x, to.y, to.z
        )
    });
    format!(
        r#"<scene version="3.0.0">
    <integrator type="path"/>
    <sensor type="perspective">
        <float name="fov" value="1"/>
        <transform name="to_world"><lookat origin="{}, {}, {}" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/><rfilter type="box"/></film>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
    <shape type="rectangle">
        <transform name="to_world"><scale value="50"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="{surface_bsdf}"><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="50"/><rotate x="1" angle="-90"/><translate y="-1"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
    </shape>
    {sheet}
</scene>"#,
        cam.x, cam.y, cam.z
    )
}

fn block_means(img: &Image, block: u32, x: u32, y: u32) -> [f64; 3] {
    let mut m = [0.0f64; 3];
    for j in y * block..(y + 1) * block {
        for i in x * block..(x + 1) * block {
            let p = img.pixels[(j * img.width + i) as usize];
            for c in 0..3 {
                m[c] += p[c] as f64;
            }
        }
    }
    m.map(|v| v / (block * block) as f64)
}

pub struct Comparison {
    pub mean_ratio: [f64; 3],
    /// Mean of z² over blocks and channels (≈ 1 when unbiased).
    pub mean_z2: f64,
    pub max_z: f64,
    pub worst_block: (u32, u32, usize),
    /// relMSE of the averaged render against the reference.
    pub rel_mse: f64,
    pub blocks: usize,
}

/// Compares independent passes with a reference image. Each block's
/// standard error comes from the spread of the passes; `ref_rel_err` is the
/// reference's own relative error (0 for a closed form).
pub fn compare(passes: &[Image], reference: &Image, block: u32, ref_rel_err: f64) -> Comparison {
    compare_by(passes, reference, block, |_, _, _, r| (ref_rel_err * r).powi(2))
}

/// As [`compare`], counting the reference's own noise block by block:
/// `ref_stderr` holds each reference pixel's standard error of the mean (the
/// spread of Mitsuba's passes, `tools/make_references.py --stderr`). The
/// reference's pixels are independent renders, so a block mean's variance
/// is the sum of its pixels' squared standard errors over the number of
/// pixels squared; it adds to the variance of the passes' mean in z.
pub fn compare_with_reference_noise(passes: &[Image], reference: &Image, ref_stderr: &Image, block: u32) -> Comparison {
    assert_eq!((ref_stderr.width, ref_stderr.height), (reference.width, reference.height), "standard-error image size");
    let n = (block * block) as f64;
    compare_by(passes, reference, block, |bx, by, c, _| {
        let mut v = 0.0f64;
        for j in by * block..(by + 1) * block {
            for i in bx * block..(bx + 1) * block {
                v += (ref_stderr.pixels[(j * ref_stderr.width + i) as usize][c] as f64).powi(2);
            }
        }
        v / (n * n)
    })
}

/// The comparison, with `ref_var(bx, by, channel, reference block mean)`
/// the variance of the reference's block mean.
fn compare_by(passes: &[Image], reference: &Image, block: u32, ref_var: impl Fn(u32, u32, usize, f64) -> f64) -> Comparison {
    let avg = average(passes);
    assert_eq!((avg.width, avg.height), (reference.width, reference.height), "image sizes differ");
    let (ma, mr) = (mean(&avg), mean(reference));
    let mean_ratio = [0, 1, 2].map(|c| if mr[c] > 0.0 { ma[c] / mr[c] } else { 1.0 + ma[c] });
    let k = passes.len() as f64;
    let (mut sum_z2, mut max_z, mut n, mut worst) = (0.0, 0.0f64, 0usize, (0, 0, 0));
    for by in 0..reference.height / block {
        for bx in 0..reference.width / block {
            let r = block_means(reference, block, bx, by);
            let per_pass: Vec<[f64; 3]> = passes.iter().map(|p| block_means(p, block, bx, by)).collect();
            for c in 0..3 {
                let m = per_pass.iter().map(|p| p[c]).sum::<f64>() / k;
                let var = per_pass.iter().map(|p| (p[c] - m).powi(2)).sum::<f64>() / (k - 1.0);
                let se2 = var / k + ref_var(bx, by, c, r[c]);
                if se2 <= 1e-14 {
                    // A noiseless block (e.g. black, or a constant background) must match exactly.
                    assert!((m - r[c]).abs() <= 1e-4 * (1.0 + r[c].abs()), "block ({bx},{by}) channel {c}: {m} vs {}", r[c]);
                    continue;
                }
                let z = (m - r[c]) / se2.sqrt();
                sum_z2 += z * z;
                n += 1;
                if z.abs() > max_z {
                    max_z = z.abs();
                    worst = (bx, by, c);
                }
            }
        }
    }
    let mut rel_mse = 0.0;
    for (a, r) in avg.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            rel_mse += ((a[c] - r[c]) as f64).powi(2) / ((r[c] as f64).powi(2) + 1e-2);
        }
    }
    rel_mse /= (avg.pixels.len() * 3) as f64;
    Comparison { mean_ratio, mean_z2: if n > 0 { sum_z2 / n as f64 } else { 0.0 }, max_z, worst_block: worst, rel_mse, blocks: n }
}

impl Comparison {
    pub fn report(&self, name: &str) {
        eprintln!(
            "{name}: mean ratio R {:.4} G {:.4} B {:.4}; blocks {} mean z² {:.2}, max |z| {:.2} at {:?}; relMSE {:.2e}",
            self.mean_ratio[0], self.mean_ratio[1], self.mean_ratio[2], self.blocks, self.mean_z2, self.max_z, self.worst_block, self.rel_mse
        );
    }

    /// Unbiased within noise: image means within `tol` (relative) and no block
    /// implausibly far from the reference given its standard error.
    pub fn assert_unbiased(&self, name: &str, tol: f64) {
        self.report(name);
        for c in 0..3 {
            assert!((self.mean_ratio[c] - 1.0).abs() < tol, "{name}: channel {c} mean ratio {:.4} outside ±{tol}", self.mean_ratio[c]);
        }
        // With 16 passes z follows Student's t (15 dof): E[z²] ≈ 1.15 and |z| > 6 has probability 2e-5.
        assert!(self.mean_z2 < 2.0, "{name}: mean z² = {:.2} — a bias larger than the noise", self.mean_z2);
        assert!(self.max_z < 6.0, "{name}: block {:?} is {:.1} standard errors off", self.worst_block, self.max_z);
    }
}

/// A scene of `shapes` under a white constant environment (radiance 1),
/// path traced without a depth limit, box filter: the furnace of energy tests.
pub fn furnace(shapes: &str, width: u32, height: u32) -> String {
    format!(
        r#"<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="-1"/></integrator>
        <sensor type="perspective">
            <float name="fov" value="40"/>
            <transform name="to_world"><lookat origin="0, 0.3, 4.5" target="0, 0, 0" up="0, 1, 0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
            <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/><rfilter type="box"/></film>
        </sensor>
        <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        {shapes}
    </scene>"#
    )
}

/// Two independent sets of passes agree: image means within `tol` and every
/// `block`² block within its noise (two-sample z over the passes' spread).
pub fn assert_agree(name: &str, a: &[Image], b: &[Image], block: u32, tol: f64) {
    let (ma, mb) = (mean(&average(a)), mean(&average(b)));
    eprintln!("{name}: means {ma:?} vs {mb:?}");
    for c in 0..3 {
        assert!(mb[c] > 0.0, "{name}: channel {c} is black");
        assert!((ma[c] / mb[c] - 1.0).abs() < tol, "{name}: channel {c} means {} vs {}", ma[c], mb[c]);
    }
    let (w, h) = (a[0].width, a[0].height);
    let block_mean = |img: &Image, bx: u32, by: u32, c: usize| {
        let mut s = 0.0f64;
        for y in by * block..(by + 1) * block {
            for x in bx * block..(bx + 1) * block {
                s += img.pixels[(y * w + x) as usize][c] as f64;
            }
        }
        s / (block * block) as f64
    };
    let stats = |set: &[Image], bx, by, c| {
        let v: Vec<f64> = set.iter().map(|i| block_mean(i, bx, by, c)).collect();
        let k = v.len() as f64;
        let m = v.iter().sum::<f64>() / k;
        (m, v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0) / k)
    };
    let (mut sum_z2, mut n, mut max_z) = (0.0, 0, 0.0f64);
    for by in 0..h / block {
        for bx in 0..w / block {
            for c in 0..3 {
                let ((m1, v1), (m2, v2)) = (stats(a, bx, by, c), stats(b, bx, by, c));
                if v1 + v2 <= 1e-14 {
                    assert!((m1 - m2).abs() <= 1e-4 * (1.0 + m2.abs()), "{name}: noiseless block ({bx},{by}) differs");
                    continue;
                }
                let z = (m1 - m2) / (v1 + v2).sqrt();
                sum_z2 += z * z;
                n += 1;
                max_z = max_z.max(z.abs());
            }
        }
    }
    let mean_z2 = sum_z2 / n.max(1) as f64;
    eprintln!("{name}: {n} blocks, mean z² {mean_z2:.2}, max |z| {max_z:.2}");
    assert!(mean_z2 < 2.0, "{name}: mean z² {mean_z2:.2}: a bias larger than the noise");
    assert!(max_z < 6.0, "{name}: a block is {max_z:.1} standard errors off");
}

/// A point light of intensity I at height h above a flat water surface
/// (η = 1.333) over a white diffuse floor (ρ) at depth d, seen straight from
/// above through the surface: light → surface → floor → surface → camera, a
/// specular–diffuse–specular path that no camera path can complete (the
/// light is a point, the surface a delta BSDF). `max_depth` 4 keeps exactly
/// this path. Under the light, at normal incidence,
///
/// E = I · T₀ / (h + d/η)²   (the refracted cone of half-angle θ/η spreads over
/// a disk of radius θ (h + d/η)), L_floor = ρ E / π, and the camera sees
/// L = T₀ L_floor / η² (radiance leaving water for air), with Fresnel's
/// T₀ = 1 − ((η − 1)/(η + 1))².
pub fn pool_scene(integrator: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
    {integrator}
    <sensor type="perspective">
        <float name="fov" value="4"/>
        <transform name="to_world"><lookat origin="0, 2, 0" target="0, 0, 0" up="0, 0, -1"/></transform>
        <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
        <film type="hdrfilm">
            <integer name="width" value="16"/>
            <integer name="height" value="16"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <emitter type="point">
        <point name="position" x="0" y="1" z="0"/>
        <rgb name="intensity" value="10, 10, 10"/>
    </emitter>
    <shape type="rectangle">
        <transform name="to_world"><scale value="10"/><rotate x="1" angle="-90"/></transform>
        <bsdf type="dielectric"><float name="int_ior" value="1.333"/><float name="ext_ior" value="1"/></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="10"/><rotate x="1" angle="-90"/><translate y="-0.5"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.8, 0.8"/></bsdf>
    </shape>
</scene>
"#
    )
}
