//! Shared checks for every BSDF (Nori's chi2test and pbrt's bsdfs_test in
//! spirit): a χ² goodness-of-fit test of `sample` against `pdf`, Helmholtz
//! reciprocity, energy conservation (albedo ≤ 1), and `sample` agreeing with
//! `eval / pdf`.

use super::{Bsdf, BsdfContext};
use crate::geometry::SurfaceInteraction;
use crate::math::{Frame, PI, Pcg32};
use crate::math::sampling::square_to_uniform_sphere;
use crate::spectrum::{Rgb, Spectrum};
use glam::{Vec2, Vec3};

pub fn dummy_interaction() -> SurfaceInteraction {
    SurfaceInteraction {
        p: Vec3::ZERO,
        t: 1.0,
        n: Vec3::Z,
        frame: Frame::from_normal(Vec3::Z),
        uv: Vec2::new(0.3, 0.6),
        dp_du: Vec3::X,
        dp_dv: Vec3::Y,
        shape: 0,
        prim: 0,
        bary: Vec2::ZERO,
        wi: Vec3::Z,
    }
}

/// A local direction at polar angle θ and azimuth φ.
pub fn incident(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// Regularised lower incomplete gamma P(a, x) (Numerical Recipes' split
/// between the series and the continued fraction).
pub(crate) fn gamma_p(a: f64, x: f64) -> f64 {
    fn ln_gamma(x: f64) -> f64 {
        // Lanczos approximation (g = 7, n = 9).
        const C: [f64; 9] = [
            0.999_999_999_999_809_9,
            676.520_368_121_885_1,
            -1_259.139_216_722_402_8,
            771.323_428_777_653_1,
            -176.615_029_162_140_6,
            12.507_343_278_686_905,
            -0.138_571_095_265_720_12,
            9.984_369_578_019_572e-6,
            1.505_632_735_149_311_6e-7,
        ];
        let x = x - 1.0;
        let mut s = C[0];
        for (i, c) in C.iter().enumerate().skip(1) {
            s += c / (x + i as f64);
        }
        let t = x + 7.5;
        0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
    }
    if x <= 0.0 {
        return 0.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let (mut sum, mut del, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-14 {
                break;
            }
        }
        sum * (-x + a * x.ln() - gln).exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-14 {
                break;
            }
        }
        1.0 - (-x + a * x.ln() - gln).exp() * h
    }
}

/// χ² test of `bsdf.sample` against `bsdf.pdf` for incident direction `wi`,
/// over a θ×φ grid of the whole sphere. Fails when the histogram of samples
/// is implausible under the pdf at significance 1 %.
pub fn chi2_test(bsdf: &Bsdf, wi: Vec3, seed: u64) {
    chi2_test_at(bsdf, wi, seed, 0.01)
}

/// As [`chi2_test`] at significance `significance` (a family of k tests
/// at 1 % overall each runs at 0.01/k, Bonferroni's correction).
pub fn chi2_test_at(bsdf: &Bsdf, wi: Vec3, seed: u64, significance: f64) {
    const THETA: usize = 10;
    const PHI: usize = 20;
    const N: usize = 500_000;
    let si = SurfaceInteraction { wi, ..dummy_interaction() };
    let mut rng = Pcg32::new(seed, 5);
    let bin_of = |v: Vec3| -> usize {
        let theta = v.z.clamp(-1.0, 1.0).acos();
        let mut phi = v.y.atan2(v.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let ti = ((theta / PI) * THETA as f32).min(THETA as f32 - 1.0) as usize;
        let pi = ((phi / (2.0 * PI)) * PHI as f32).min(PHI as f32 - 1.0) as usize;
        ti * PHI + pi
    };
    let mut observed = vec![0.0f64; THETA * PHI];
    let mut valid = 0usize;
    for _ in 0..N {
        let s: Option<super::BsdfSample<Rgb>> = bsdf.sample(&BsdfContext::RADIANCE, &si, wi, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()), &());
        if let Some(s) = s {
            if s.lobe.intersects(super::Lobe::DELTA) {
                continue;
            }
            assert!((s.wo.length() - 1.0).abs() < 1e-3, "sampled direction is not unit length");
            observed[bin_of(s.wo)] += 1.0;
            valid += 1;
        }
    }
    // Expected counts: integrate the pdf over each bin (midpoint rule, 32 θ
    // × 128 φ points per bin: fine enough for glossy lobes a few degrees
    // wide, and for the thin arcs along the horizon that grazing reflection
    // makes of them).
    let mut expected = vec![0.0f64; THETA * PHI];
    const SUB: usize = 32;
    const SUB_PHI: usize = 128;
    for ti in 0..THETA {
        for pi in 0..PHI {
            let mut sum = 0.0f64;
            for a in 0..SUB {
                for b in 0..SUB_PHI {
                    let theta = (ti as f64 + (a as f64 + 0.5) / SUB as f64) * std::f64::consts::PI / THETA as f64;
                    let phi = (pi as f64 + (b as f64 + 0.5) / SUB_PHI as f64) * 2.0 * std::f64::consts::PI / PHI as f64;
                    let wo = incident(theta as f32, phi as f32);
                    sum += bsdf.pdf::<Rgb>(&BsdfContext::RADIANCE, &si, wi, wo, &()) as f64 * theta.sin();
                }
            }
            let d_area = (std::f64::consts::PI / THETA as f64) * (2.0 * std::f64::consts::PI / PHI as f64) / (SUB * SUB_PHI) as f64;
            expected[ti * PHI + pi] = sum * d_area * N as f64;
        }
    }
    let (chsq, dof) = chi2_statistic(&observed, &expected, N);
    assert!(dof > 0, "too few bins for a χ² test");
    let p_value = 1.0 - gamma_p(dof as f64 / 2.0, chsq / 2.0);
    let total_expected: f64 = expected.iter().sum();
    assert!(
        (total_expected - valid as f64).abs() < 0.02 * N as f64,
        "pdf integrates to {} but {} of {} samples were valid",
        total_expected / N as f64,
        valid,
        N
    );
    if p_value <= significance {
        for i in 0..expected.len() {
            if expected[i] > 100.0 || observed[i] > 100.0 {
                eprintln!("bin θ{} φ{}: observed {} expected {:.1}", i / PHI, i % PHI, observed[i], expected[i]);
            }
        }
    }
    assert!(p_value > significance, "χ² test rejected the sampling routine: χ²={chsq:.1}, dof={dof}, p={p_value:.2e} (wi {wi})");
}

/// χ² test of a direction sampler against its density `pdf` (solid
/// angle): θ bins are dense over the polar cap θ < `cap` (where narrow
/// lobes put their samples) and coarse beyond it, down to the south pole.
/// Fails when the histogram is implausible at significance `significance`,
/// or when the pdf does not integrate to the fraction of valid samples.
pub fn chi2_directions(mut sample: impl FnMut() -> Option<Vec3>, pdf: impl Fn(Vec3) -> f64, cap: f32, significance: f64) {
    const INNER: usize = 10;
    const OUTER: usize = 6;
    const PHI: usize = 16;
    const N: usize = 100_000;
    let cap = cap as f64;
    let pi = std::f64::consts::PI;
    let edge = |t: usize| if t <= INNER { cap * t as f64 / INNER as f64 } else { cap + (pi - cap) * (t - INNER) as f64 / OUTER as f64 };
    let bin_of = |v: Vec3| -> usize {
        let theta = (v.z.clamp(-1.0, 1.0) as f64).acos();
        let t = if theta < cap {
            ((theta / cap) * INNER as f64) as usize
        } else {
            INNER + (((theta - cap) / (pi - cap)) * OUTER as f64) as usize
        };
        let mut phi = (v.y as f64).atan2(v.x as f64);
        if phi < 0.0 {
            phi += 2.0 * pi;
        }
        let p = ((phi / (2.0 * pi)) * PHI as f64) as usize;
        t.min(INNER + OUTER - 1) * PHI + p.min(PHI - 1)
    };
    let mut observed = vec![0.0f64; (INNER + OUTER) * PHI];
    let mut valid = 0usize;
    for _ in 0..N {
        if let Some(v) = sample() {
            assert!((v.length() - 1.0).abs() < 1e-3, "sampled direction is not unit length");
            observed[bin_of(v)] += 1.0;
            valid += 1;
        }
    }
    let mut expected = vec![0.0f64; (INNER + OUTER) * PHI];
    const ST: usize = 32;
    const SP: usize = 8;
    for t in 0..INNER + OUTER {
        let (t0, t1) = (edge(t), edge(t + 1));
        for p in 0..PHI {
            let mut sum = 0.0;
            for a in 0..ST {
                let theta = t0 + (t1 - t0) * (a as f64 + 0.5) / ST as f64;
                for b in 0..SP {
                    let phi = (p as f64 + (b as f64 + 0.5) / SP as f64) * 2.0 * pi / PHI as f64;
                    sum += pdf(incident(theta as f32, phi as f32)) * theta.sin();
                }
            }
            expected[t * PHI + p] = sum * (t1 - t0) / ST as f64 * (2.0 * pi / PHI as f64) / SP as f64 * N as f64;
        }
    }
    chi2_verdict(&observed, &expected, valid, N, significance);
}

/// Pearson's χ² of `observed` against `expected` counts (of `n` samples)
/// and its degrees of freedom, pooling the bins of expectation below 5 (the
/// χ² approximation needs ≥ 5); samples in a bin of zero pdf fail the test.
fn chi2_statistic(observed: &[f64], expected: &[f64], n: usize) -> (f64, i32) {
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut chsq, mut dof) = (0.0f64, 0i32);
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    for &i in &order {
        if expected[i] == 0.0 {
            assert!(observed[i] < 1e-3 * n as f64 + 1.0, "{} samples fell where the pdf is zero", observed[i]);
            continue;
        }
        if expected[i] < 5.0 {
            pool_e += expected[i];
            pool_o += observed[i];
            continue;
        }
        let diff = observed[i] - expected[i];
        chsq += diff * diff / expected[i];
        dof += 1;
    }
    if pool_e > 0.0 {
        let diff = pool_o - pool_e;
        chsq += diff * diff / pool_e;
        dof += 1;
    }
    dof -= 1;
    (chsq, dof)
}

/// Pools bins of small expectation, then rejects at `significance`.
fn chi2_verdict(observed: &[f64], expected: &[f64], valid: usize, n: usize, significance: f64) {
    let (chsq, dof) = chi2_statistic(observed, expected, n);
    let total_expected: f64 = expected.iter().sum();
    assert!(
        (total_expected - valid as f64).abs() < 0.02 * n as f64,
        "pdf integrates to {} but {} of {} samples were valid",
        total_expected / n as f64,
        valid,
        n
    );
    if dof <= 0 {
        // Everything in one bin (a lobe narrower than a bin): nothing to test
        // beyond the total.
        return;
    }
    let p_value = 1.0 - gamma_p(dof as f64 / 2.0, chsq / 2.0);
    assert!(p_value > significance, "χ² test rejected the sampling routine: χ²={chsq:.1}, dof={dof}, p={p_value:.2e}");
}

/// Directional albedo by sampling the BSDF: the mean sample weight
/// (delta lobes included).
pub fn estimate_albedo_sampled(bsdf: &Bsdf, wi: Vec3, n: usize, seed: u64) -> [f32; 3] {
    let si = SurfaceInteraction { wi, ..dummy_interaction() };
    let mut rng = Pcg32::new(seed, 13);
    let mut sum = [0.0f64; 3];
    for _ in 0..n {
        if let Some(s) = bsdf.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()), &()) {
            for c in 0..3 {
                sum[c] += s.weight[c] as f64;
            }
        }
    }
    sum.map(|s| (s / n as f64) as f32)
}

/// f(wi, wo) = f(wo, wi) for random direction pairs (eval includes |cos θ_o|,
/// so it is divided out first).
pub fn check_reciprocity(bsdf: &Bsdf, seed: u64) {
    let si = dummy_interaction();
    let mut rng = Pcg32::new(seed, 7);
    for _ in 0..2000 {
        let a = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
        let b = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
        if a.z.abs() < 1e-3 || b.z.abs() < 1e-3 {
            continue;
        }
        let fab: Rgb = bsdf.eval(&BsdfContext::RADIANCE, &si, a, b, &());
        let fba: Rgb = bsdf.eval(&BsdfContext::RADIANCE, &si, b, a, &());
        for c in 0..3 {
            let x = fab[c] / b.z.abs();
            let y = fba[c] / a.z.abs();
            assert!((x - y).abs() <= 1e-4 * (1.0 + x.abs()), "f(a,b)={x} but f(b,a)={y}");
        }
    }
}

/// Directional albedo ∫ f cos dω for `wi`, by uniform sphere sampling of eval.
pub fn estimate_albedo(bsdf: &Bsdf, wi: Vec3, n: usize, seed: u64) -> [f32; 3] {
    let si = SurfaceInteraction { wi, ..dummy_interaction() };
    let mut rng = Pcg32::new(seed, 9);
    let mut sum = [0.0f64; 3];
    for _ in 0..n {
        let wo = square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
        let f: Rgb = bsdf.eval(&BsdfContext::RADIANCE, &si, wi, wo, &());
        for c in 0..3 {
            sum[c] += f[c] as f64 * 4.0 * std::f64::consts::PI;
        }
    }
    sum.map(|s| (s / n as f64) as f32)
}

/// `sample`'s weight and pdf agree with `eval` and `pdf` at the sampled
/// direction (radiance transport, every lobe). Fails too if fewer than
/// 10 % of the samples are valid: a BSDF asked from its scattering side
/// must scatter (a sampler returning `None` everywhere proves nothing).
pub fn check_sample_consistency(bsdf: &Bsdf, wi: Vec3, seed: u64) {
    check_sample_consistency_ctx(bsdf, &BsdfContext::RADIANCE, wi, seed)
}

/// As [`check_sample_consistency`], under the context `ctx`.
pub fn check_sample_consistency_ctx(bsdf: &Bsdf, ctx: &BsdfContext, wi: Vec3, seed: u64) {
    const N: usize = 5000;
    let si = SurfaceInteraction { wi, ..dummy_interaction() };
    let mut rng = Pcg32::new(seed, 11);
    let mut valid = 0usize;
    for _ in 0..N {
        let Some(s) = bsdf.sample::<Rgb>(ctx, &si, wi, rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()), &()) else {
            continue;
        };
        valid += 1;
        assert!(ctx.wants(s.lobe), "sampled lobe {:?} that the context does not want", s.lobe);
        if s.lobe.intersects(super::Lobe::DELTA) {
            // A delta lobe adds nothing to eval/pdf: for a purely specular BSDF
            // both vanish at the sampled direction (a mixed one, like plastic,
            // keeps its smooth lobes there).
            if !bsdf.lobes().intersects(super::Lobe::SMOOTH) {
                assert_eq!(bsdf.pdf::<Rgb>(ctx, &si, wi, s.wo, &()), 0.0, "pdf must be zero on a delta lobe");
                assert!(bsdf.eval::<Rgb>(ctx, &si, wi, s.wo, &()).is_zero(), "eval must be zero on a delta lobe");
            }
            assert!(s.weight.is_finite() && s.pdf > 0.0);
            continue;
        }
        let pdf = bsdf.pdf::<Rgb>(ctx, &si, wi, s.wo, &());
        assert!((pdf - s.pdf).abs() <= 1e-3 * pdf.max(1e-3), "pdf {pdf} vs sampled {}", s.pdf);
        let f: Rgb = bsdf.eval(ctx, &si, wi, s.wo, &());
        for c in 0..3 {
            let w = f[c] / pdf;
            assert!((w - s.weight[c]).abs() <= 1e-3 * (1.0 + w), "weight {} vs eval/pdf {w} ({ctx:?}, wi {wi}, wo {}, {:?})", s.weight[c], s.wo, s.lobe);
        }
        assert!(s.weight.is_finite());
    }
    assert!(valid * 10 >= N, "only {valid} of {N} samples were valid: the BSDF does not sample from this side");
}

#[test]
fn gamma_p_known_values() {
    // P(1, x) = 1 − e^(−x); χ² with 2 dof at 5.991 has p = 0.05.
    assert!((gamma_p(1.0, 2.0) - (1.0 - (-2.0f64).exp())).abs() < 1e-10);
    assert!((1.0 - gamma_p(1.0, 5.991 / 2.0) - 0.05).abs() < 1e-3);
    assert!((gamma_p(5.0, 5.0) - 0.559_506_714_9).abs() < 1e-8);
    assert!((gamma_p(30.0, 25.0) - 0.182_103_916).abs() < 1e-6);
}

#[test]
fn sample_consistency_rejects_a_bsdf_that_never_samples() {
    // A diffuse BSDF asked from its back side returns no samples: the
    // check must not pass vacuously.
    use crate::texture::Texture;
    let b = Bsdf::Diffuse(super::Diffuse { reflectance: Texture::constant(Rgb::new(0.5, 0.5, 0.5)) });
    let back = Vec3::new(0.3, 0.1, -0.9).normalize();
    assert!(std::panic::catch_unwind(|| check_sample_consistency(&b, back, 1)).is_err());
    // Neither does it when the context wants no lobe the BSDF has.
    let ctx = BsdfContext::RADIANCE.with_lobes(super::Lobe::GLOSSY);
    assert!(std::panic::catch_unwind(|| check_sample_consistency_ctx(&b, &ctx, Vec3::Z, 2)).is_err());
    check_sample_consistency(&b, Vec3::Z, 3);
}
