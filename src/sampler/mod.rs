//! Samplers: the numbers that drive every Monte Carlo decision of a sample.
//!
//! A scene names its sampler inside the `<sensor>`; every sampler takes
//! `sample_count` (samples per pixel, default 4) and `seed` (default 0):
//!
//! | plugin | file | what |
//! |---|---|---|
//! | `independent` | [`independent`] | independent uniform numbers (Mitsuba's default) |
//! | `stratified` | [`stratified`] | jittered strata per dimension, `sample_count` rounded up to a square |
//! | `multijitter` | [`multijitter`] | Kensler's correlated multi-jitter: stratified in 2-D and in 1-D |
//! | `orthogonal` | [`orthogonal`] | orthogonal-array (Bush) samples: stratified in every `strength`-D projection |
//! | `ldsampler` | [`ldsampler`] | Mitsuba's (0,2)-sequence sampler, shuffled and digitally shifted per dimension |
//! | `sobol` | [`sobol`] | Owen-scrambled Sobol (0,2)-sequence, padded per dimension (Snell's own) |
//! | `zsobol` | [`zsobol`] | `sobol` with Morton-ordered sample indices: error spread as blue noise (Snell's own) |
//!
//! Which to use: `multijitter` or `sobol` (power-of-two sample counts) cut
//! the error of directly and diffusely lit scenes most per sample; `zsobol`
//! gives the same per-pixel error spread as blue noise; `independent` stays
//! the default for scenes that name none, as in Mitsuba.
//!
//! Samples are addressable: [`Sampler::start`] gives the sampler of sample
//! `index` of pixel (x, y), and every number it draws is a pure function of
//! (seed, pixel, index, dimension), where the dimension counts the draws of
//! the sample so far. So any sample can be rendered on its own: the image does
//! not depend on the thread count, the order of the work, or how the sample
//! range is split into passes (or over machines).
//!
//! A dimension is one call: `next_1d` draws one number, `next_2d` one 2-D
//! point of the sampler's pattern (a stratified cell, a (0,2)-net point), so
//! that the integrators' 2-D decisions (pixel position, lens, BSDF and light
//! samples) get well-distributed pairs. Where a pattern has no more
//! dimensions to give (`stratified`/`ldsampler` past `dimension`,
//! orthogonal arrays past their columns), the sampler pads with the next set
//! of columns under a new random permutation or, past `dimension`, with
//! hashed uniform numbers.

pub mod independent;
pub mod ldsampler;
pub mod multijitter;
pub mod orthogonal;
pub mod sobol;
pub mod stratified;
pub mod zsobol;

use crate::math::rng::mix64;
use crate::scene::error::Result;
use crate::scene::props::Props;
use glam::Vec2;

/// The samplers' names as scenes write them, in the order of the table above.
pub const NAMES: [&str; 7] = ["independent", "stratified", "multijitter", "orthogonal", "ldsampler", "sobol", "zsobol"];

/// A sampler as the scene describes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplerSpec {
    /// Samples per pixel, as the sampler uses it (see [`SamplerSpec::set_sample_count`]).
    pub sample_count: u32,
    pub seed: u64,
    pub kind: SamplerKind,
}

/// Which sampler, with its own parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SamplerKind {
    Independent,
    Stratified { jitter: bool, dimension: u32 },
    Multijitter { jitter: bool },
    Orthogonal { jitter: bool, strength: u32 },
    LdSampler { dimension: u32 },
    Sobol,
    /// `log2_res`: log2 of the film's larger side, rounded up (the Morton
    /// curve covers a 2^log2_res square).
    ZSobol { log2_res: u32 },
}

impl Default for SamplerSpec {
    fn default() -> SamplerSpec {
        SamplerSpec { sample_count: 4, seed: 0, kind: SamplerKind::Independent }
    }
}

impl SamplerKind {
    pub fn name(&self) -> &'static str {
        match self {
            SamplerKind::Independent => "independent",
            SamplerKind::Stratified { .. } => "stratified",
            SamplerKind::Multijitter { .. } => "multijitter",
            SamplerKind::Orthogonal { .. } => "orthogonal",
            SamplerKind::LdSampler { .. } => "ldsampler",
            SamplerKind::Sobol => "sobol",
            SamplerKind::ZSobol { .. } => "zsobol",
        }
    }

    /// The sample count this sampler uses when asked for `n` (Mitsuba's
    /// rounding: a square for `stratified`, a power-of-two square for
    /// `ldsampler`, …); at least 1 and at most 2^24 in every case but
    /// `orthogonal` of a high strength (capped by its loader).
    pub fn round_sample_count(&self, n: u32) -> u32 {
        let n = n.max(1);
        match *self {
            SamplerKind::Stratified { .. } => stratified::round_sample_count(n),
            SamplerKind::Multijitter { .. } => multijitter::round_sample_count(n),
            SamplerKind::Orthogonal { strength, .. } => orthogonal::round_sample_count(n, strength),
            SamplerKind::LdSampler { .. } => ldsampler::round_sample_count(n),
            _ => n,
        }
    }

    /// The count a sample's pattern is built for when the film takes `n`
    /// samples per pixel. `n` has been rounded once already (by
    /// [`SamplerSpec::set_sample_count`]); rounding is idempotent for every
    /// kind but `multijitter`, whose Mitsuba rounding is not (26 → 28 → 36)
    /// and whose grid takes any count, so it keeps `n`: a pattern of 36 cut
    /// to the 28 samples taken would lose its strata.
    fn pattern_count(&self, n: u32) -> u32 {
        match *self {
            SamplerKind::Multijitter { .. } => n.max(1),
            _ => self.round_sample_count(n),
        }
    }
}

impl SamplerSpec {
    /// Sets the sample count, rounded as the sampler needs it (what `--spp`
    /// and the scene's `sample_count` go through).
    pub fn set_sample_count(&mut self, n: u32) {
        self.sample_count = self.kind.round_sample_count(n);
    }

    /// Tells a sampler that orders pixels along a curve how large the film
    /// is (`zsobol`); the others ignore it.
    pub fn fit_film(&mut self, width: u32, height: u32) {
        if let SamplerKind::ZSobol { log2_res } = &mut self.kind {
            *log2_res = zsobol::log2_res(width, height);
        }
    }
}

impl SamplerSpec {
    /// The sampler `plugin` with the parameters of its XML node (the loader
    /// has checked that `plugin` is one of [`NAMES`]).
    pub fn from_props(plugin: &str, props: &Props) -> Result<SamplerSpec> {
        let sample_count = props.int_checked("sample_count", 4, |v| (1..=1 << 24).contains(&v), "between 1 and 16777216")? as u32;
        let seed = props.int_checked("seed", 0, |v| v >= 0, "non-negative")? as u64;
        let dimension = |props: &Props| -> Result<u32> {
            Ok(props.int_checked("dimension", u32::MAX as i64, |v| (1..=u32::MAX as i64).contains(&v), "a positive number of draws")? as u32)
        };
        let kind = match plugin {
            "stratified" => SamplerKind::Stratified { jitter: props.bool("jitter", true)?, dimension: dimension(props)? },
            "multijitter" => SamplerKind::Multijitter { jitter: props.bool("jitter", true)? },
            "orthogonal" => {
                let jitter = props.bool("jitter", true)?;
                let strength = props.int_checked("strength", 2, |v| orthogonal::STRENGTHS.contains(&(v as u32)) && v > 0, "between 2 and 6")? as u32;
                let rounded = orthogonal::round_sample_count(sample_count, strength);
                if rounded > 1 << 24 {
                    return Err(props.error_at(
                        "sample_count",
                        format!("an orthogonal array of strength {strength} needs a prime power of samples: {sample_count} rounds up to {rounded}, above the limit of 16777216"),
                    ));
                }
                SamplerKind::Orthogonal { jitter, strength }
            }
            "ldsampler" => SamplerKind::LdSampler { dimension: dimension(props)? },
            "sobol" => SamplerKind::Sobol,
            "zsobol" => SamplerKind::ZSobol { log2_res: 0 },
            _ => SamplerKind::Independent,
        };
        let mut spec = SamplerSpec { sample_count, seed, kind };
        spec.set_sample_count(sample_count);
        Ok(spec)
    }
}

/// The sampler of one sample: call [`Sampler::start`], then draw.
pub struct Sampler {
    method: Method,
}

enum Method {
    Independent(independent::Independent),
    Stratified(stratified::Stratified),
    Multijitter(multijitter::Multijitter),
    Orthogonal(orthogonal::Orthogonal),
    LdSampler(ldsampler::LdSampler),
    Sobol(sobol::Sobol),
    ZSobol(zsobol::ZSobol),
}

/// The samples of one pixel: what [`Sampler::start`] computes that is the
/// same for all of them (the pixel's sequence seed, the pattern's size),
/// made once, so that a renderer taking several samples of a pixel in a
/// row starts each with [`PixelSamples::start`] alone. The draws are those
/// of `Sampler::start` (which goes through here).
#[derive(Clone, Copy, Debug)]
pub struct PixelSamples {
    spec: SamplerSpec,
    x: u32,
    y: u32,
    /// [`pixel_seed`] of (seed, x, y).
    pixel: u64,
    /// The pattern's sample count ([`SamplerKind::pattern_count`]).
    count: u32,
}

impl PixelSamples {
    pub fn new(spec: &SamplerSpec, x: u32, y: u32) -> PixelSamples {
        PixelSamples { spec: *spec, x, y, pixel: pixel_seed(spec.seed, x, y), count: spec.kind.pattern_count(spec.sample_count) }
    }

    /// The pixel this is for.
    #[inline]
    pub fn pixel(&self) -> (u32, u32) {
        (self.x, self.y)
    }

    /// The sampler of sample `index` of this pixel.
    #[inline(always)]
    pub fn start(&self, index: u32) -> Sampler {
        // The default sampler inline (a hash and a PCG32 seeding), the
        // others out of line, as the draws are.
        if let SamplerKind::Independent = self.spec.kind {
            return Sampler { method: Method::Independent(independent::Independent::start(self.pixel, index)) };
        }
        self.start_patterned(index)
    }

    /// Starts sample `index` of this pixel, takes its first draws as a
    /// camera sample does (the wavelength draw if `spectral`, else its
    /// skip; then the position in the pixel) and pushes the sampler onto
    /// `out`. Returns the wavelength draw (0 without it) and the position.
    ///
    /// The same draws as [`PixelSamples::start`] followed by
    /// [`Sampler::next_1d`] or [`Sampler::skip_1d`] and
    /// [`Sampler::next_2d`]; for the default sampler its state stays in
    /// registers through them and is written into `out` once (a `Sampler`
    /// drawn from on the stack and copied in after was written with 8-byte
    /// stores and read back with 16-byte loads: a store-forwarding stall
    /// per sample).
    #[inline(always)]
    pub fn start_camera_into(&self, index: u32, spectral: bool, out: &mut Vec<Sampler>) -> (f32, Vec2) {
        if let SamplerKind::Independent = self.spec.kind {
            let mut s = independent::Independent::start(self.pixel, index);
            let u = if spectral { s.next_1d() } else { s.skip_1d(); 0.0 };
            let pos = s.next_2d();
            out.push(Sampler { method: Method::Independent(s) });
            return (u, pos);
        }
        let mut s = self.start_patterned(index);
        let u = if spectral { s.next_1d() } else { s.skip_1d(); 0.0 };
        let pos = s.next_2d();
        out.push(s);
        (u, pos)
    }

    #[inline(never)]
    fn start_patterned(&self, index: u32) -> Sampler {
        let (spec, count, x, y) = (&self.spec, self.count, self.x, self.y);
        let id = || SampleId::new(self.pixel, count, index);
        let method = match spec.kind {
            SamplerKind::Independent => Method::Independent(independent::Independent::start(self.pixel, index)),
            SamplerKind::Stratified { jitter, dimension } => Method::Stratified(stratified::Stratified::start(id(), jitter, dimension)),
            SamplerKind::Multijitter { jitter } => Method::Multijitter(multijitter::Multijitter::start(id(), jitter)),
            SamplerKind::Orthogonal { jitter, strength } => Method::Orthogonal(orthogonal::Orthogonal::start(id(), jitter, strength)),
            SamplerKind::LdSampler { dimension } => Method::LdSampler(ldsampler::LdSampler::start(id(), dimension)),
            SamplerKind::Sobol => Method::Sobol(sobol::Sobol::start(id())),
            SamplerKind::ZSobol { log2_res } => match zsobol::ZSobol::start(spec.seed, count, log2_res, x, y, index) {
                Some(z) => Method::ZSobol(z),
                // Off the film's Morton square (light tracing's path numbers):
                // the padded Sobol sequence of that "pixel".
                None => Method::Sobol(sobol::Sobol::start(id())),
            },
        };
        Sampler { method }
    }
}

/// Where a sample is: the per-pixel sequence seed and the sample's index.
/// Samplers whose pattern covers `count` samples treat index `count + i` as
/// sample `i` of a fresh, independently randomized pattern (`block` 1).
#[derive(Clone, Copy, Debug)]
pub(crate) struct SampleId {
    /// Hash of (seed, pixel, block).
    pub pixel_seed: u64,
    /// Index within the pattern, < count.
    pub index: u32,
    pub count: u32,
}

impl SampleId {
    /// Sample `index` of the pixel whose sequence seed is `pixel`
    /// ([`pixel_seed`]).
    fn new(pixel: u64, count: u32, index: u32) -> SampleId {
        let count = count.max(1);
        let block = index / count;
        SampleId { pixel_seed: hash(pixel, block as u64), index: index % count, count }
    }
}

impl Sampler {
    /// The sampler of sample `index` of pixel (`x`, `y`) (pixel coordinates
    /// in the full film, so a crop renders the same samples as the full
    /// render there). Light tracing addresses its paths the same way, with
    /// its own pixel numbering.
    pub fn start(spec: &SamplerSpec, x: u32, y: u32, index: u32) -> Sampler {
        PixelSamples::new(spec, x, y).start(index)
    }
    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        // The default sampler inline (a few integer instructions); the
        // others out of line, so that this stays small enough to inline
        // into the integrators.
        if let Method::Independent(s) = &mut self.method {
            return s.next_1d();
        }
        self.next_1d_patterned()
    }

    /// The patterned samplers' draws, each its own out-of-line function:
    /// the dispatch is a jump, and each draw saves only the registers it
    /// uses (one function with every sampler inlined saved them all).
    #[inline(never)]
    fn next_1d_patterned(&mut self) -> f32 {
        match &mut self.method {
            Method::Independent(s) => s.next_1d(),
            Method::Stratified(s) => s.next_1d(),
            Method::Multijitter(s) => s.next_1d(),
            Method::Orthogonal(s) => s.next_1d(),
            Method::LdSampler(s) => s.next_1d(),
            Method::Sobol(s) => s.next_1d(),
            Method::ZSobol(s) => s.next_1d(),
        }
    }

    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        if let Method::Independent(s) = &mut self.method {
            return s.next_2d();
        }
        // `ldsampler`'s and `multijitter`'s draws inline as well (straight
        // code; `permute`'s cycle-walking loop stays out of line): the
        // caller's work overlaps the draw, where a call waited for it (2–4 %
        // of a render; docs/performance.md, "What the patterned samplers cost"). `sobol`
        // gained nothing from it and stays out of line.
        match &mut self.method {
            Method::LdSampler(s) => s.next_2d(),
            Method::Multijitter(s) => s.next_2d(),
            _ => self.next_2d_patterned(),
        }
    }

    /// The out-of-line 2-D draws (the kinds `next_2d` draws inline never
    /// come here; their arms complete the match).
    #[inline(never)]
    fn next_2d_patterned(&mut self) -> Vec2 {
        match &mut self.method {
            Method::Independent(s) => s.next_2d(),
            Method::Stratified(s) => s.next_2d(),
            Method::Multijitter(s) => s.next_2d(),
            Method::Orthogonal(s) => s.next_2d(),
            Method::LdSampler(s) => s.next_2d(),
            Method::Sobol(s) => s.next_2d(),
            Method::ZSobol(s) => s.next_2d(),
        }
    }
}

impl Sampler {
    /// Takes a 1-D draw without computing it: the next draws are those
    /// after a [`Sampler::next_1d`] (for a draw whose value is unused, as
    /// the wavelength draw in RGB mode).
    #[inline]
    pub fn skip_1d(&mut self) {
        match &mut self.method {
            Method::Independent(s) => s.skip_1d(),
            Method::Stratified(s) => s.dim += 1,
            Method::Multijitter(s) => s.dim += 1,
            Method::Orthogonal(s) => s.coord += 1,
            Method::LdSampler(s) => s.dim += 1,
            Method::Sobol(s) => s.dim += 1,
            Method::ZSobol(s) => s.dim += 1,
        }
    }

    /// Continues the sample at draw number `dim`: the next draw is the one
    /// a fresh sample would make after `dim` draws. Splitting integrators
    /// give each split branch its own fixed block of dimensions, so that a
    /// branch's draws stay aligned across the pixel's samples (and keep the
    /// pattern's stratification) however many draws the branches before it
    /// took. `independent` has nothing to align: its stream just goes on.
    pub fn set_dimension(&mut self, dim: u32) {
        match &mut self.method {
            Method::Independent(_) => {}
            Method::Stratified(s) => s.dim = dim,
            Method::Multijitter(s) => s.dim = dim,
            Method::Orthogonal(s) => s.coord = dim,
            Method::LdSampler(s) => s.dim = dim,
            Method::Sobol(s) => s.dim = dim,
            Method::ZSobol(s) => s.dim = dim,
        }
    }
}

// ----------------------------------------------------------------- shared tools

/// The largest float below 1.
pub(crate) const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// The seed of pixel (x, y)'s sequence.
#[inline]
pub(crate) fn pixel_seed(seed: u64, x: u32, y: u32) -> u64 {
    let pixel = ((y as u64) << 32) | x as u64;
    mix64(mix64(seed ^ 0x5eed_0000_0000_0000) ^ pixel)
}

/// A well-mixed hash of a well-mixed word `a` (a sequence seed) and any `b`.
#[inline]
pub(crate) fn hash(a: u64, b: u64) -> u64 {
    mix64(a ^ b.wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// A 32-bit fixed-point fraction as a float in [0, 1) (24 bits, never 1.0).
#[inline]
pub(crate) fn unit(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Two uniform numbers for (sequence, index, dimension), for jitter and for
/// dimensions past a pattern's end.
#[inline]
pub(crate) fn uniform2(pixel_seed: u64, index: u32, dim: u32) -> (f32, f32) {
    let key = ((index as u64) << 32) | dim as u64;
    let h = hash(pixel_seed ^ 0x6a09_e667_f3bc_c909, key);
    (unit(h as u32), unit((h >> 32) as u32))
}

/// One uniform number for (sequence, index, dimension).
#[inline]
pub(crate) fn uniform(pixel_seed: u64, index: u32, dim: u32) -> f32 {
    uniform2(pixel_seed, index, dim).0
}

/// Element `i` of a pseudo-random permutation of [0, n) chosen by `seed`.
///
/// For n = 2^k (the samplers' common case, drawn several times per sample)
/// two rounds of a random odd multiply and a xorshift by ⌈k/2⌉, between an
/// xor and an add of seed bits: every step is a bijection on k bits, the
/// multiplies carry low bits up and the shifts carry high bits down. It
/// costs a third of Kensler's hash (which was a fifth of a multi-jittered
/// Cornell box's instructions); over random seeds each index goes to every
/// element equally often (test below). Other n: Kensler's hash (2013, "Correlated Multi-Jittered
/// Sampling"), a bijection on the next power of two, cycle-walked down to
/// [0, n), out of line.
#[inline(always)]
pub(crate) fn permute(i: u32, n: u32, seed: u32) -> u32 {
    if n.is_power_of_two() {
        return permute_pow2(i, n - 1, seed);
    }
    permute_walk(i, n, seed)
}

/// [`permute`] for n = w + 1 a power of two (w = 0 gives 0).
#[inline(always)]
fn permute_pow2(i: u32, w: u32, seed: u32) -> u32 {
    let bits = u32::BITS - w.leading_zeros();
    let shift = bits.div_ceil(2);
    let mut x = (i ^ seed) & w;
    x = x.wrapping_mul((seed >> 16) | 1) & w;
    x ^= x >> shift;
    x = x.wrapping_mul(0x2c1b_3c6d) & w;
    x ^= x >> shift;
    x.wrapping_add(seed >> 8) & w
}

/// [`permute`] for `n` not a power of two: cycle-walk the hash on the next
/// power of two down to [0, n).
#[inline(never)]
fn permute_walk(mut i: u32, n: u32, seed: u32) -> u32 {
    if n <= 1 {
        return 0;
    }
    let p = seed;
    let mut w = n - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
        i = kensler_round(i, p, w);
        if i < n {
            break;
        }
    }
    ((i as u64 + p as u64) % n as u64) as u32
}

/// One round of Kensler's hash: a bijection on [0, w] (w + 1 a power of
/// two).
#[inline(always)]
fn kensler_round(mut i: u32, p: u32, w: u32) -> u32 {
    i ^= p;
    i = i.wrapping_mul(0xe170_893d);
    i ^= p >> 16;
    i ^= (i & w) >> 4;
    i ^= p >> 8;
    i = i.wrapping_mul(0x0929_eb3f);
    i ^= p >> 23;
    i ^= (i & w) >> 1;
    i = i.wrapping_mul(1 | p >> 27);
    i = i.wrapping_mul(0x6935_fa69);
    i ^= (i & w) >> 11;
    i = i.wrapping_mul(0x74dc_b303);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0x9e50_1cc3);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0xc860_a3df);
    i &= w;
    i ^= i >> 5;
    i
}

/// 64 random bits for dimension `dim` of a sequence (permutation seeds).
#[inline]
pub(crate) fn dim_hash(pixel_seed: u64, dim: u32) -> u64 {
    hash(pixel_seed, dim as u64)
}

#[cfg(test)]
pub(crate) mod testing {
    //! Tools shared by the samplers' tests.
    use super::*;

    pub fn spec(kind: SamplerKind, n: u32, seed: u64) -> SamplerSpec {
        let mut s = SamplerSpec { sample_count: n, seed, kind };
        s.set_sample_count(n);
        s.fit_film(64, 64);
        s
    }

    /// The points of draw number `draw` (earlier draws are `pattern`: true for
    /// a 2-D draw) of every sample of a pixel.
    pub fn points(spec: &SamplerSpec, x: u32, y: u32, pattern: &[bool], draw_2d: bool) -> Vec<Vec2> {
        (0..spec.sample_count)
            .map(|i| {
                let mut s = Sampler::start(spec, x, y, i);
                for &two in pattern {
                    if two {
                        s.next_2d();
                    } else {
                        s.next_1d();
                    }
                }
                if draw_2d { s.next_2d() } else { Vec2::new(s.next_1d(), 0.5) }
            })
            .collect()
    }

    /// Squared L2 star discrepancy of 2-D points (Warnock's formula).
    pub fn l2_star_discrepancy2(p: &[Vec2]) -> f64 {
        let n = p.len() as f64;
        let mut a = 0.0;
        for q in p {
            a += (1.0 - (q.x as f64).powi(2)) * (1.0 - (q.y as f64).powi(2)) / 4.0;
        }
        let mut b = 0.0;
        for q in p {
            for r in p {
                b += (1.0 - (q.x.max(r.x) as f64)) * (1.0 - (q.y.max(r.y) as f64));
            }
        }
        1.0 / 9.0 - 2.0 / n * a + b / (n * n)
    }

    /// Mean squared L2 star discrepancy over `pixels` pixels of the first
    /// 2-D draw and of a later one (after 1-D, 2-D, 1-D draws).
    pub fn mean_discrepancy(spec: &SamplerSpec, pixels: u32) -> f64 {
        let mut sum = 0.0;
        for p in 0..pixels {
            sum += l2_star_discrepancy2(&points(spec, p, 3, &[], true));
            sum += l2_star_discrepancy2(&points(spec, p, 3, &[false, true, false], true));
        }
        sum / (2 * pixels) as f64
    }

    /// Asserts that the points hit every cell of a `cols` × `rows` grid
    /// exactly `per` times.
    pub fn assert_cells(p: &[Vec2], cols: u32, rows: u32, per: u32, what: &str) {
        for q in p {
            assert!((0.0..1.0).contains(&q.x) && (0.0..1.0).contains(&q.y), "{what}: {q} outside [0,1)²");
        }
        let hits = hits(p, cols, rows);
        assert!(hits.iter().all(|&h| h == per), "{what}: {cols}×{rows} cells hit {hits:?}, expected {per} each");
    }

    /// How many points fall in each cell of a `cols` × `rows` grid.
    pub fn hits(p: &[Vec2], cols: u32, rows: u32) -> Vec<u32> {
        let mut hits = vec![0u32; (cols * rows) as usize];
        for q in p {
            let cx = ((q.x * cols as f32) as u32).min(cols - 1);
            let cy = ((q.y * rows as f32) as u32).min(rows - 1);
            hits[(cy * cols + cx) as usize] += 1;
        }
        hits
    }

    /// Asserts the (0, m, 2)-net property: every elementary interval of area
    /// 1/n (n = 2^m points) holds exactly one point.
    pub fn assert_net(p: &[Vec2], what: &str) {
        let n = p.len() as u32;
        assert!(n.is_power_of_two());
        let m = n.trailing_zeros();
        for a in 0..=m {
            assert_cells(p, 1 << a, 1 << (m - a), 1, what);
        }
    }

    /// The sampler's draws are a pure function of (seed, pixel, index, dimension).
    pub fn assert_addressable(kind: SamplerKind) {
        let spec = spec(kind, 16, 7);
        let draw = |spec: &SamplerSpec, x, y, i| {
            let mut s = Sampler::start(spec, x, y, i);
            let mut v = Vec::new();
            for d in 0..40 {
                if d % 3 == 1 {
                    v.push(s.next_1d());
                } else {
                    let p = s.next_2d();
                    v.extend([p.x, p.y]);
                }
            }
            v
        };
        let a = draw(&spec, 3, 5, 9);
        // Drawing other samples in between changes nothing.
        let _ = draw(&spec, 3, 5, 8);
        let _ = draw(&spec, 4, 5, 9);
        assert_eq!(a, draw(&spec, 3, 5, 9));
        assert_ne!(a, draw(&spec, 3, 5, 10));
        assert_ne!(a, draw(&spec, 5, 3, 9));
        let other = SamplerSpec { seed: 8, ..spec };
        assert_ne!(a, draw(&other, 3, 5, 9));
        // Every draw in [0, 1), also past the pattern's sample count.
        for i in [0, 15, 16, 40] {
            let mut s = Sampler::start(&spec, 1, 2, i);
            for _ in 0..200 {
                let p = s.next_2d();
                let q = s.next_1d();
                assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y) && (0.0..1.0).contains(&q));
            }
        }
    }

    /// The mean of a smooth 5-D integrand over all samples of a pixel, for
    /// 60 independent seeds: no bias from the pattern (the spread of the 60
    /// estimates gives the standard error), and no more noise than
    /// independent samples.
    pub fn assert_unbiased(kind: SamplerKind) {
        let f = |a: Vec2, b: f32, c: Vec2| (a.x * a.y) as f64 * b as f64 * (c.x + c.y * c.y) as f64;
        let exact = 0.25 * 0.5 * (0.5 + 1.0 / 3.0);
        let estimates = |kind: SamplerKind| -> Vec<f64> {
            (0..60u64)
                .map(|seed| {
                    let spec = spec(kind, 16, seed);
                    let (mut sum, mut n) = (0.0, 0.0);
                    for p in 0..25 {
                        for i in 0..spec.sample_count {
                            let mut s = Sampler::start(&spec, p % 5, p / 5, i);
                            s.next_1d();
                            let a = s.next_2d();
                            let b = s.next_1d();
                            let c = s.next_2d();
                            sum += f(a, b, c);
                            n += 1.0;
                        }
                    }
                    sum / n
                })
                .collect()
        };
        let stats = |e: &[f64]| {
            let k = e.len() as f64;
            let m = e.iter().sum::<f64>() / k;
            let var = e.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0);
            (m, (var / k).sqrt())
        };
        let (mean, se) = stats(&estimates(kind));
        let (_, se_independent) = stats(&estimates(SamplerKind::Independent));
        assert!((mean - exact).abs() < 4.5 * se, "{}: mean {mean} vs {exact} (standard error {se:.2e})", kind.name());
        assert!(se < 1.2 * se_independent, "{}: standard error {se:.2e} above independent's {se_independent:.2e}", kind.name());
    }

    /// The first 2-D draws are better spread than independent points.
    pub fn assert_below_independent(kind: SamplerKind, n: u32) {
        let ours = spec(kind, n, 11);
        let indep = spec(SamplerKind::Independent, ours.sample_count, 11);
        let (a, b) = (mean_discrepancy(&ours, 24), mean_discrepancy(&indep, 24));
        assert!(a < 0.7 * b, "{}: L2 star discrepancy² {a:.3e} not below independent's {b:.3e}", kind.name());
    }
}

#[cfg(test)]
mod set_dimension_tests {
    use super::testing::spec;
    use super::*;

    /// One sampler of every kind, with parameters that exercise them.
    const EVERY_KIND: [SamplerKind; 7] = [
        SamplerKind::Independent,
        SamplerKind::Stratified { jitter: true, dimension: 3 },
        SamplerKind::Multijitter { jitter: true },
        SamplerKind::Orthogonal { jitter: true, strength: 2 },
        SamplerKind::LdSampler { dimension: 4 },
        SamplerKind::Sobol,
        SamplerKind::ZSobol { log2_res: 0 },
    ];

    /// `permute` is a bijection of [0, n) for every n, and over random seeds
    /// (hash outputs, as the samplers pass) each index goes to every
    /// element equally often: chi² over the n elements below its 1e-5
    /// quantile. (The images of two indices are not a uniform pair for small
    /// n, neither with this hash nor with Kensler's: both compose maps that
    /// are affine on two bits, which reach 2 of the 6 linear parts there.
    /// The renderer's error per sample is the measure that counts: see the
    /// sampler benchmarks in docs/performance.md.)
    #[test]
    fn permutations_are_bijections_that_move_each_index_uniformly() {
        for n in (1..=70).chain([127, 128, 256, 1000, 1024]) {
            for seed in [0u32, 1, 0xdead_beef, u32::MAX] {
                let mut seen = vec![false; n as usize];
                for i in 0..n {
                    let p = permute(i, n, seed);
                    assert!(p < n && !seen[p as usize], "permute(·, {n}, {seed:#x}) is not a bijection");
                    seen[p as usize] = true;
                }
            }
        }
        let mut failures = vec![];
        for n in [2u32, 4, 8, 12, 16, 64, 100, 256] {
            for i in [0, 1, n / 2, n - 1] {
                let per_cell = 400;
                let mut counts = vec![0u32; n as usize];
                for s in 0..(n * per_cell) as u64 {
                    let seed = mix64(s ^ 0x1234_5678_9abc_def0) as u32;
                    counts[permute(i, n, seed) as usize] += 1;
                }
                let chi2: f64 = counts.iter().map(|&c| (c as f64 - per_cell as f64).powi(2) / per_cell as f64).sum();
                let dof = (n - 1) as f64;
                // Wilson–Hilferty: the 1 − 1e-5 quantile of chi² (z = 4.265).
                let limit = dof * (1.0 - 2.0 / (9.0 * dof) + 4.265 * (2.0 / (9.0 * dof)).sqrt()).powi(3);
                if chi2 >= limit {
                    failures.push(format!("n = {n}, index {i}: chi² {chi2:.1} above {limit:.1} ({dof} dof)"));
                }
            }
        }
        assert!(failures.is_empty(), "indices not moved uniformly:\n{}", failures.join("\n"));
    }

    /// `skip_1d` leaves a sample where `next_1d` would, for every sampler.
    #[test]
    fn skip_1d_is_an_unused_next_1d() {
        for kind in EVERY_KIND {
            let spec = spec(kind, 16, 3);
            for index in [0, 5, 16, 40] {
                let (mut drawn, mut skipped) = (Sampler::start(&spec, 2, 3, index), Sampler::start(&spec, 2, 3, index));
                for d in 0..12 {
                    if d % 4 == 0 {
                        drawn.next_1d();
                        skipped.skip_1d();
                    } else {
                        assert_eq!(drawn.next_2d(), skipped.next_2d(), "{}: draw {d}", kind.name());
                        assert_eq!(drawn.next_1d(), skipped.next_1d(), "{}: draw {d}", kind.name());
                    }
                }
            }
        }
    }

    /// `start_camera_into` draws what `start` and the camera's first draws
    /// give, and pushes a sampler that goes on as that one does, for every
    /// sampler, with and without the wavelength draw.
    #[test]
    fn start_camera_into_is_start_and_the_first_draws() {
        for kind in EVERY_KIND {
            let spec = spec(kind, 16, 3);
            let pixel = PixelSamples::new(&spec, 5, 7);
            for spectral in [false, true] {
                let mut queue = vec![];
                for index in [0, 5, 16, 40] {
                    let mut want = pixel.start(index);
                    let u = if spectral { want.next_1d() } else { want.skip_1d(); 0.0 };
                    let pos = want.next_2d();
                    let (got_u, got_pos) = pixel.start_camera_into(index, spectral, &mut queue);
                    assert_eq!((got_u.to_bits(), got_pos), (u.to_bits(), pos), "{}: sample {index}", kind.name());
                    let Some(got) = queue.last_mut() else { panic!("nothing pushed") };
                    for d in 0..6 {
                        assert_eq!(got.next_2d(), want.next_2d(), "{}: sample {index}, draw {d}", kind.name());
                        assert_eq!(got.next_1d().to_bits(), want.next_1d().to_bits(), "{}: sample {index}, draw {d}", kind.name());
                    }
                }
                assert_eq!(queue.len(), 4);
            }
        }
    }

    /// After `set_dimension(d)` a sample draws what a fresh one draws after
    /// d draws, for every sampler (`independent` just goes on).
    #[test]
    fn set_dimension_continues_at_that_draw() {
        let kinds = [
            SamplerKind::Stratified { jitter: true, dimension: u32::MAX },
            SamplerKind::Multijitter { jitter: true },
            SamplerKind::Orthogonal { jitter: true, strength: 2 },
            SamplerKind::LdSampler { dimension: u32::MAX },
            SamplerKind::Sobol,
            SamplerKind::ZSobol { log2_res: 0 },
        ];
        for kind in kinds {
            let spec = spec(kind, 16, 3);
            for d in [0u32, 1, 5, 4096, 8192 + 7] {
                let mut fresh = Sampler::start(&spec, 2, 3, 5);
                for _ in 0..d {
                    fresh.next_1d();
                }
                let mut jumped = Sampler::start(&spec, 2, 3, 5);
                jumped.next_2d();
                jumped.next_1d();
                jumped.set_dimension(d);
                let (a, b) = ((fresh.next_2d(), fresh.next_1d()), (jumped.next_2d(), jumped.next_1d()));
                assert_eq!(a, b, "{}: dimension {d}", kind.name());
            }
        }
    }
}
