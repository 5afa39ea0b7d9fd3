//! `birefringent` — a smooth interface between an isotropic medium and a
//! uniaxial crystal (calcite, quartz, sapphire, rutile, ice): the seed's index
//! of refraction that "depends on the wavelength *and the polarization state*".
//!
//! | parameter | type | default | meaning |
//! |---|---|---|---|
//! | `ordinary_ior` | float / string | `calcite` | n_o: a number, a crystal (`calcite`, `quartz`, `sapphire`, `rutile`, `ice`: its ordinary index), a constant name as for `dielectric` (`water`, …) or a dispersive form (`sellmeier(…)`, `cauchy(…)`, see `dispersion.rs`) |
//! | `extraordinary_ior` | float / string | `calcite` | n_e, the same forms (a crystal's name gives its extraordinary index) |
//! | `optic_axis` | vector | (0, 0, 1) | the crystal's optic axis in the shape's local frame (transformed by the shape's `to_world`) |
//! | `ext_ior` | float / string | `air` (1.000277) | exterior index (isotropic), as for `dielectric` |
//! | `specular_reflectance` | rgb / spectrum / float / texture | 1 | scale of reflection (not physical) |
//! | `specular_transmittance` | rgb / spectrum / float / texture | 1 | scale of transmission (not physical) |
//!
//! ```xml
//! <shape type="cube">
//!     <transform name="to_world"><scale x="1" y="1" z="0.25"/></transform>
//!     <bsdf type="birefringent">
//!         <string name="ordinary_ior" value="calcite"/>
//!         <string name="extraordinary_ior" value="calcite"/>
//!         <vector name="optic_axis" x="1" y="0" z="1"/>
//!     </bsdf>
//! </shape>
//! ```
//!
//! Mitsuba 3 has no birefringent material (nor pbrt-v4, Cycles, LuxCore):
//! this plugin is Snell's own and no Mitsuba reference exists for it.
//!
//! # Physics
//!
//! The crystal's dielectric tensor is ε = n_o² (I − a aᵀ) + n_e² a aᵀ for the
//! optic axis a. A plane wave of wave vector k (in units of the vacuum wave
//! number, |k| = its phase index) is either *ordinary* (|k| = n_o, field E ⟂
//! k and a) or *extraordinary*, whose k lies on the ellipsoid
//! (a·k)²/n_o² + |a×k|²/n_e² = 1, i.e. 1/n(θ)² = cos²θ/n_o² + sin²θ/n_e² for
//! a wave normal at θ to the axis; its D ⟂ k in the plane of k and a, its
//! E = ε⁻¹D, and its energy (ray) direction s ∝ εk is the ellipsoid's normal,
//! walking off the wave normal by ρ with
//! tan ρ = (n_o² − n_e²) sin θ cos θ / (n_e² cos²θ + n_o² sin²θ).
//!
//! At the interface (z = 0 in the shading frame, the crystal below) every
//! wave shares the tangential wave vector K of the incident one (Snell's law
//! for each kind); the normal components follow from |k|² = n² (isotropic,
//! ordinary) or a quadratic (extraordinary). The four outgoing amplitudes
//! (two reflected, two transmitted waves) solve the continuity of tangential
//! E and H = k × E — the 4 × 4 linear system from which Weidlich and Wilkie
//! ("Realistic rendering of birefringency in uniaxial crystals", ACM TOG
//! 27(1), 2008) derive their closed forms; Snell solves it numerically in
//! complex arithmetic, which covers total internal reflection of either wave
//! (its normal component becomes imaginary: an evanescent wave that carries
//! no flux and shifts the phases of the reflected ones). Flux through the
//! interface (the normal component of the Poynting vector ½Re(E × H*)) gives
//! each outgoing wave's share, and they add to one.
//!
//! Each outgoing wave's field, scaled by √(its flux / the incident flux),
//! in the canonical Stokes frame of its ray direction, makes a 2 × 2 Jones
//! matrix from the incident wave's frame, and that a Mueller matrix (the
//! coherency matrix J C J†). Inside the crystal a path is an o-ray or an
//! e-ray, linearly polarised along its mode; an o or e incident wave's
//! Jones matrix takes only the component along its mode.
//!
//! Radiance: the étendue of a beam is d²K dA (tangential wave vector and
//! area, both unchanged across the interface), and d²K = |cos θ_s| dω_s / κ
//! with κ the Gaussian curvature of the wave-vector surface at k (1/n² for a
//! sphere of radius n; det M / |M k|⁴ for the extraordinary ellipsoid
//! kᵀMk = 1). So L κ is carried across: L_out = T L_in κ_in / κ_out, the
//! dielectric's (η_i/η_t)² for isotropic media. Importance transport is not
//! scaled (as `dielectric`).
//!
//! Sampling: the camera path arriving along wi is traced back by time
//! reversal (a lossless crystal is reciprocal): the wave sent along −wi
//! splits into a reflected and two refracted waves (outside: reflection,
//! o and e; inside: o and e reflections and the refraction out), whose
//! polarisation-averaged flux shares are the lobe probabilities; the sample
//! follows the chosen wave's ray (energy) direction, and its weight is the
//! exact polarised transfer from that wave back to wi. Unpolarised modes
//! use the flux share of that transfer (for light entering from outside,
//! averaged over polarisations; for an o or e ray, its full flux), so the
//! double image shows in `rgb` too. A sample into (or reflected inside) the
//! crystal as an e-ray carries [`Lobe::EXTRAORDINARY`]; integrators pass it
//! back in [`BsdfContext::extraordinary`] at the next vertex.
//!
//! Placement: the optic axis is given in the shape's local frame. BSDFs may
//! be shared between shapes (a `<ref>`); the loader gives each shape its own
//! copy of a `birefringent` BSDF with the axis turned by that shape's
//! `to_world` (as a vector: scaled and sheared shapes turn it with them).
//! Inside a `twosided`/`blendbsdf`, or a shape instanced by `instance`, the
//! axis is taken in world space.
//!
//! With n_o = n_e (at every wavelength) the model is exactly `dielectric`:
//! it samples through that code, sample for sample.
//!
//! Named crystals (Sellmeier: n² = 1 + Σ Bᵢ λ²/(λ² − Cᵢ), λ in µm; a term
//! with C = 0 is a constant; forms A + B/(λ² − C) are rewritten as
//! (A − 1 − B/C) + (B/C) λ²/(λ² − C)):
//!
//! | name | source |
//! |---|---|
//! | `calcite` | G. Ghosh, Opt. Commun. 163, 95 (1999), CaCO₃ at 20 °C |
//! | `quartz` | G. Ghosh, Opt. Commun. 163, 95 (1999), crystalline SiO₂ at 20 °C |
//! | `sapphire` | I. H. Malitson, M. J. Dodge, JOSA 62, 1405 (1972), Al₂O₃ |
//! | `rutile` | J. R. DeVore, JOSA 41, 416 (1951), TiO₂ |
//! | `ice` | constants n_o = 1.3090, n_e = 1.3104 at 589 nm, −3 °C (P. V. Hobbs, *Ice Physics*, 1974, after Ehringhaus); no dispersion model |

use super::dielectric::{AIR, Dielectric};
use super::dispersion::{DispersiveInterface, IorSpectrum, parse_ior_expr};
use super::{BsdfContext, BsdfModel, BsdfSample, Lobe, TransportMode};
use crate::geometry::SurfaceInteraction;
use crate::math::Transform;
use crate::scene::error::Result;
use crate::scene::loader::PluginLoader;
use crate::scene::props::Props;
use crate::spectrum::mueller::stokes_basis;
use crate::spectrum::{Rgb, Spectrum};
use crate::texture::Texture;
use glam::{DVec3, Mat4, Vec2, Vec3, Vec4};
use num_complex::Complex64 as C;

// ------------------------------------------------------------ named crystals

/// A named crystal: (name, ordinary Sellmeier (B, C), extraordinary (B, C)).
type Crystal = (&'static str, (&'static [f64], &'static [f64]), (&'static [f64], &'static [f64]));

const CRYSTALS: &[Crystal] = &[
    (
        // Ghosh: n² = A + B λ²/(λ² − C) + D λ²/(λ² − E), A − 1 as a C = 0 term.
        "calcite",
        (&[0.733_587_49, 0.964_643_45, 1.828_314_54], &[0.0, 1.943_252_03e-2, 120.0]),
        (&[0.358_596_95, 0.824_278_30, 0.144_291_28], &[0.0, 1.066_895_43e-2, 120.0]),
    ),
    (
        "quartz",
        (&[0.286_041_41, 1.070_440_83, 1.102_022_42], &[0.0, 1.005_859_97e-2, 100.0]),
        (&[0.288_518_04, 1.095_099_24, 1.156_624_75], &[0.0, 1.021_018_64e-2, 100.0]),
    ),
    (
        // Malitson & Dodge give the resonance wavelengths 0.0726631, 0.1193242,
        // 18.028251 µm (o) and 0.0740288, 0.1216529, 20.072248 µm (e); C = λᵢ².
        "sapphire",
        (&[1.431_349_3, 0.650_547_13, 5.341_402_1], &[0.005_279_925_3, 0.014_237_27, 325.017_84]),
        (&[1.503_975_9, 0.550_691_41, 6.592_737_9], &[0.005_480_263, 0.014_799_43, 402.898_14]),
    ),
    (
        // DeVore: n_o² = 5.913 + 0.2441/(λ² − 0.0803), n_e² = 7.197 + 0.3322/(λ² − 0.0843).
        "rutile",
        (&[5.913 - 1.0 - 0.2441 / 0.0803, 0.2441 / 0.0803], &[0.0, 0.0803]),
        (&[7.197 - 1.0 - 0.3322 / 0.0843, 0.3322 / 0.0843], &[0.0, 0.0843]),
    ),
];

/// Ice Ih at 589 nm (no dispersion model).
const ICE: (f32, f32) = (1.3090, 1.3104);

/// The crystal names, for `ordinary_ior` / `extraordinary_ior`.
pub fn crystal_names() -> Vec<&'static str> {
    CRYSTALS.iter().map(|c| c.0).chain(["ice"]).collect()
}

/// The ordinary (`extraordinary` false) or extraordinary index of the named crystal.
pub fn crystal_index(name: &str, extraordinary: bool) -> Option<IorSpectrum> {
    let lower = name.trim().to_ascii_lowercase();
    if lower == "ice" {
        return Some(IorSpectrum::Constant(if extraordinary { ICE.1 } else { ICE.0 }));
    }
    let c = CRYSTALS.iter().find(|c| c.0 == lower)?;
    let (b, cc) = if extraordinary { c.2 } else { c.1 };
    Some(IorSpectrum::Sellmeier { b: b.to_vec(), c: cc.to_vec() })
}

// -------------------------------------------------------- complex 3-vectors

#[derive(Clone, Copy, Debug)]
struct CV {
    x: C,
    y: C,
    z: C,
}

impl CV {
    fn real(v: DVec3) -> CV {
        CV { x: C::new(v.x, 0.0), y: C::new(v.y, 0.0), z: C::new(v.z, 0.0) }
    }
    fn dot(self, o: CV) -> C {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    fn dot_real(self, v: DVec3) -> C {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
    fn cross(self, o: CV) -> CV {
        CV { x: self.y * o.z - self.z * o.y, y: self.z * o.x - self.x * o.z, z: self.x * o.y - self.y * o.x }
    }
    fn scale(self, s: C) -> CV {
        CV { x: self.x * s, y: self.y * s, z: self.z * s }
    }
    fn add(self, o: CV) -> CV {
        CV { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
    fn norm(self) -> f64 {
        (self.x.norm_sqr() + self.y.norm_sqr() + self.z.norm_sqr()).sqrt()
    }
    fn conj(self) -> CV {
        CV { x: self.x.conj(), y: self.y.conj(), z: self.z.conj() }
    }
    fn re(self) -> DVec3 {
        DVec3::new(self.x.re, self.y.re, self.z.re)
    }
    fn normalized(self) -> CV {
        let n = self.norm();
        if n > 0.0 { self.scale(C::new(1.0 / n, 0.0)) } else { self }
    }
}

/// √d as a complex number: i√(−d) for negative d.
fn csqrt(d: f64) -> C {
    if d >= 0.0 { C::new(d.sqrt(), 0.0) } else { C::new(0.0, (-d).sqrt()) }
}

// ------------------------------------------------------------- the crystal

/// The kind of a plane wave at the interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wave {
    /// In the isotropic exterior (either polarisation).
    Outside,
    Ordinary,
    Extraordinary,
}

/// A plane wave: wave vector (units of the vacuum wave number), unit field
/// E, H = k × E, and whether it propagates (else it is evanescent).
#[derive(Clone, Copy, Debug)]
struct PlaneWave {
    k: CV,
    e: CV,
    h: CV,
    propagating: bool,
}

impl PlaneWave {
    fn new(k: CV, e: CV, propagating: bool) -> PlaneWave {
        let e = e.normalized();
        PlaneWave { k, e, h: k.cross(e), propagating }
    }
    /// Normal component of the time-averaged Poynting vector, ½Re(E × H*)·z.
    fn flux(&self) -> f64 {
        0.5 * self.e.cross(self.h.conj()).z.re
    }
}

/// One wave leaving an interaction (see [`Uniaxial::scatter`]).
#[derive(Clone, Copy, Debug)]
pub struct Scattered {
    pub wave: Wave,
    /// Direction of energy travel (unit, local frame); `None` if evanescent.
    pub ray: Option<DVec3>,
    /// Flux-normalised Jones matrix `jones[row][col]`: rows the outgoing field
    /// along (x, y) of the canonical Stokes frame of `ray`, columns the
    /// incident field along (x, y) of the incident ray's frame.
    pub jones: [[C; 2]; 2],
    /// The share of the incident flux this wave carries: averaged over
    /// polarisations for an incident wave from outside, all of it for an
    /// incident o or e wave.
    pub power: f64,
    /// The Gaussian curvature of the wave-vector surface at this wave's k.
    pub kappa: f64,
    /// The wave's phase index |k|.
    pub index: f64,
}

/// The waves leaving one incident wave's interaction with the interface.
#[derive(Clone, Copy, Debug)]
pub struct Interaction {
    pub incident_kappa: f64,
    pub incident_index: f64,
    /// Outside incidence: reflection, o and e transmission. Inside: o and e
    /// reflection, transmission out.
    pub out: [Scattered; 3],
}

/// A uniaxial crystal below the plane z = 0 (local frame), an isotropic
/// medium above; all indices absolute.
#[derive(Clone, Copy, Debug)]
pub struct Uniaxial {
    pub n_ext: f64,
    pub n_o: f64,
    pub n_e: f64,
    /// Unit optic axis (local frame).
    pub axis: DVec3,
}

impl Uniaxial {
    /// 1/n_o² − 1/n_e².
    fn c(&self) -> f64 {
        1.0 / (self.n_o * self.n_o) - 1.0 / (self.n_e * self.n_e)
    }

    /// M k for the extraordinary wave-vector ellipsoid kᵀMk = 1.
    fn m_apply(&self, k: DVec3) -> DVec3 {
        k / (self.n_e * self.n_e) + self.axis * (self.c() * self.axis.dot(k))
    }

    /// The index of an extraordinary wave whose normal makes angle θ with
    /// the axis: 1/n(θ)² = cos²θ/n_o² + sin²θ/n_e².
    pub fn extraordinary_index(&self, cos_theta: f64) -> f64 {
        let c2 = cos_theta * cos_theta;
        1.0 / (c2 / (self.n_o * self.n_o) + (1.0 - c2) / (self.n_e * self.n_e)).sqrt()
    }

    /// The wave vector of a wave of kind `wave` whose energy travels along `d`.
    pub fn wave_vector(&self, wave: Wave, d: DVec3) -> DVec3 {
        match wave {
            Wave::Outside => d * self.n_ext,
            Wave::Ordinary => d * self.n_o,
            Wave::Extraordinary => {
                // k ∝ M⁻¹ s, scaled onto the ellipsoid.
                let minv = d * (self.n_e * self.n_e) + self.axis * ((self.n_o * self.n_o - self.n_e * self.n_e) * self.axis.dot(d));
                minv / d.dot(minv).sqrt()
            }
        }
    }

    /// The energy (ray) direction of a propagating wave of kind `wave` with wave vector `k`.
    pub fn ray_direction(&self, wave: Wave, k: DVec3) -> DVec3 {
        match wave {
            Wave::Extraordinary => self.m_apply(k).normalize(),
            _ => k.normalize(),
        }
    }

    /// The étendue factor κ (see the module doc) of a wave.
    pub fn kappa(&self, wave: Wave, k: DVec3) -> f64 {
        match wave {
            Wave::Outside => 1.0 / (self.n_ext * self.n_ext),
            Wave::Ordinary => 1.0 / (self.n_o * self.n_o),
            Wave::Extraordinary => {
                let det = 1.0 / (self.n_e.powi(4) * self.n_o * self.n_o);
                det / self.m_apply(k).length_squared().powi(2)
            }
        }
    }

    /// The fields of the ordinary and extraordinary waves of wave vector `k`:
    /// E_o ∝ k × a, D_e = k × E_o, E_e = ε⁻¹ D_e. Along the axis (where the
    /// two are one) E_o is a fixed direction across it.
    fn crystal_fields(&self, k: CV) -> (CV, CV) {
        let a = CV::real(self.axis);
        let mut e_o = k.cross(a);
        if e_o.norm() < 1e-9 * k.norm().max(1e-30) {
            e_o = CV::real(self.axis.any_orthonormal_vector());
        }
        let e_o = e_o.normalized();
        let d = k.cross(e_o);
        let inv = 1.0 / (self.n_e * self.n_e) - 1.0 / (self.n_o * self.n_o);
        let e_e = d.scale(C::new(1.0 / (self.n_o * self.n_o), 0.0)).add(a.scale(a.dot(d) * inv));
        (e_o, e_e.normalized())
    }

    /// The crystal's o and e waves with tangential wave vector `kt`,
    /// travelling (or decaying) downwards (`up` false) or upwards.
    fn crystal_waves(&self, kt: DVec3, up: bool) -> [(Wave, PlaneWave); 2] {
        let sign = if up { 1.0 } else { -1.0 };
        let kt2 = kt.length_squared();
        let d_o = self.n_o * self.n_o - kt2;
        let k_o = CV::real(kt).add(CV::real(DVec3::Z).scale(csqrt(d_o) * sign));
        // Extraordinary: (K + qz)ᵀM(K + qz) = 1, A q² + B q + C = 0; the root
        // with the larger q has its ray (the ellipsoid's normal) upwards.
        let (a, c) = (self.axis, self.c());
        let qa = 1.0 / (self.n_e * self.n_e) + c * a.z * a.z;
        let qb = 2.0 * c * a.dot(kt) * a.z;
        let qc = kt2 / (self.n_e * self.n_e) + c * a.dot(kt).powi(2) - 1.0;
        let disc = qb * qb - 4.0 * qa * qc;
        let q_e = (C::new(-qb, 0.0) + csqrt(disc) * sign) / (2.0 * qa);
        let k_e = CV::real(kt).add(CV::real(DVec3::Z).scale(q_e));
        let o = PlaneWave::new(k_o, self.crystal_fields(k_o).0, d_o >= 0.0);
        let e = PlaneWave::new(k_e, self.crystal_fields(k_e).1, disc >= 0.0);
        [(Wave::Ordinary, o), (Wave::Extraordinary, e)]
    }

    /// The exterior's s and p waves with tangential wave vector `kt`, upwards.
    fn outside_waves(&self, kt: DVec3) -> [(Wave, PlaneWave); 2] {
        let d = self.n_ext * self.n_ext - kt.length_squared();
        let k = CV::real(kt).add(CV::real(DVec3::Z).scale(csqrt(d)));
        let s = DVec3::Z.cross(kt).try_normalize().unwrap_or(DVec3::X);
        let s = CV::real(s);
        let p = s.cross(k);
        [(Wave::Outside, PlaneWave::new(k, s, d >= 0.0)), (Wave::Outside, PlaneWave::new(k, p, d >= 0.0))]
    }

    /// A wave of kind `incident` whose energy travels along `d` (unit, local;
    /// downwards for `Outside`, upwards for o and e) meets the interface: the
    /// reflected and transmitted waves, with Jones matrices between the
    /// canonical Stokes frames given by `basis` (the frame's x axis for a
    /// local direction; y = d × x). `None` for a direction that does not
    /// meet the interface from the incident wave's side.
    pub fn scatter(&self, incident: Wave, d: DVec3, basis: &dyn Fn(DVec3) -> DVec3) -> Option<Interaction> {
        let outside = incident == Wave::Outside;
        if (outside && !(d.z < -1e-7)) || (!outside && !(d.z > 1e-7)) {
            return None;
        }
        let k_in = self.wave_vector(incident, d);
        let kt = DVec3::new(k_in.x, k_in.y, 0.0);
        let (x_in, y_in) = {
            let x = basis(d);
            (x, d.cross(x))
        };
        let kc = CV::real(k_in);
        // The incident fields: both polarisations outside, the mode's inside.
        let mode_field = match incident {
            Wave::Outside => None,
            Wave::Ordinary => Some(self.crystal_fields(kc).0),
            Wave::Extraordinary => Some(self.crystal_fields(kc).1),
        };
        let fields: Vec<CV> = match mode_field {
            None => vec![CV::real(x_in), CV::real(y_in)],
            Some(e) => vec![e],
        };
        let (reflected, transmitted) =
            if outside { (self.outside_waves(kt), self.crystal_waves(kt, false)) } else { (self.crystal_waves(kt, false), self.outside_waves(kt)) };
        let waves = [reflected[0], reflected[1], transmitted[0], transmitted[1]];
        // Tangential E and H continuous: Σ_r a W − Σ_t a W = −incident.
        let mut m = [[C::new(0.0, 0.0); 4]; 4];
        for (j, (_, w)) in waves.iter().enumerate() {
            let sign = if j < 2 { 1.0 } else { -1.0 };
            for (row, v) in [w.e.x, w.e.y, w.h.x, w.h.y].into_iter().enumerate() {
                m[row][j] = v * sign;
            }
        }
        let mut amplitudes = Vec::with_capacity(fields.len());
        let mut flux_in = 0.0;
        for e in &fields {
            let inc = PlaneWave::new(kc, *e, true);
            flux_in = inc.flux().abs();
            let rhs = [-inc.e.x, -inc.e.y, -inc.h.x, -inc.h.y];
            amplitudes.push(solve4(m, rhs)?);
        }
        if !(flux_in > 0.0) {
            return None;
        }
        // Group the outgoing waves: the two exterior ones make one beam.
        let groups: [(Wave, &[usize]); 3] = if outside {
            [(Wave::Outside, &[0, 1]), (Wave::Ordinary, &[2]), (Wave::Extraordinary, &[3])]
        } else {
            [(Wave::Ordinary, &[0]), (Wave::Extraordinary, &[1]), (Wave::Outside, &[2, 3])]
        };
        let half = if outside { 0.5 } else { 1.0 };
        let out = groups.map(|(wave, members)| {
            let first = waves[members[0]].1;
            let k_re = first.k.re();
            let kappa = if first.propagating { self.kappa(wave, k_re) } else { 0.0 };
            let index = first.k.norm();
            let mut s = Scattered { wave, ray: None, jones: [[C::new(0.0, 0.0); 2]; 2], power: 0.0, kappa, index };
            if !first.propagating {
                return s;
            }
            let ray = self.ray_direction(wave, k_re);
            let x_out = basis(ray);
            let y_out = ray.cross(x_out);
            let mut columns = [[C::new(0.0, 0.0); 2]; 2];
            for (col, amp) in amplitudes.iter().enumerate() {
                let mut field = CV::real(DVec3::ZERO);
                for &j in members {
                    let w = waves[j].1;
                    let scale = (w.flux().abs() / flux_in).sqrt();
                    field = field.add(w.e.scale(amp[j] * scale));
                }
                columns[col] = [field.dot_real(x_out), field.dot_real(y_out)];
                s.power += half * (field.dot_real(x_out).norm_sqr() + field.dot_real(y_out).norm_sqr());
            }
            s.jones = match mode_field {
                None => [[columns[0][0], columns[1][0]], [columns[0][1], columns[1][1]]],
                Some(e) => {
                    // Only the incident field's component along the mode passes.
                    let (mx, my) = (e.re().dot(x_in), e.re().dot(y_in));
                    [[columns[0][0] * mx, columns[0][0] * my], [columns[0][1] * mx, columns[0][1] * my]]
                }
            };
            s.ray = Some(ray);
            s
        });
        Some(Interaction { incident_kappa: self.kappa(incident, k_in), incident_index: k_in.length(), out })
    }
}

/// Solves the 4 × 4 complex system `m x = b` by Gaussian elimination with
/// partial pivoting; `None` if it is singular.
fn solve4(mut m: [[C; 4]; 4], mut b: [C; 4]) -> Option<[C; 4]> {
    for col in 0..4 {
        let pivot = (col..4).max_by(|&i, &j| m[i][col].norm().total_cmp(&m[j][col].norm()))?;
        if !(m[pivot][col].norm() > 1e-14) {
            return None;
        }
        m.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..4 {
            let f = m[row][col] / m[col][col];
            for k in col..4 {
                let v = m[col][k];
                m[row][k] -= f * v;
            }
            let v = b[col];
            b[row] -= f * v;
        }
    }
    let mut x = [C::new(0.0, 0.0); 4];
    for row in (0..4).rev() {
        let mut s = b[row];
        for k in row + 1..4 {
            s -= m[row][k] * x[k];
        }
        x[row] = s / m[row][row];
    }
    Some(x)
}

/// The Mueller matrix of Jones matrix `j` (Stokes S0 = |Ex|² + |Ey|²,
/// S1 = |Ex|² − |Ey|², S2 = 2Re(Ex Ey*), S3 = −2Im(Ex Ey*), the convention
/// of `spectrum::mueller`'s interfaces): the coherency matrix J C J†.
pub fn jones_to_mueller(j: [[C; 2]; 2]) -> Mat4 {
    let z = C::new(0.0, 0.0);
    let h = C::new(0.5, 0.0);
    let basis = [
        [[h, z], [z, h]],
        [[h, z], [z, -h]],
        [[z, h], [h, z]],
        [[z, C::new(0.0, -0.5)], [C::new(0.0, 0.5), z]],
    ];
    let cols = basis.map(|c| {
        // J C J†
        let mut jc = [[z; 2]; 2];
        for r in 0..2 {
            for k in 0..2 {
                jc[r][k] = j[r][0] * c[0][k] + j[r][1] * c[1][k];
            }
        }
        let mut o = [[z; 2]; 2];
        for r in 0..2 {
            for k in 0..2 {
                o[r][k] = jc[r][0] * j[k][0].conj() + jc[r][1] * j[k][1].conj();
            }
        }
        Vec4::new((o[0][0] + o[1][1]).re as f32, (o[0][0] - o[1][1]).re as f32, (2.0 * o[0][1].re) as f32, (-2.0 * o[0][1].im) as f32)
    });
    Mat4::from_cols(cols[0], cols[1], cols[2], cols[3])
}

// ---------------------------------------------------------------- the BSDF

#[derive(Clone, Debug)]
pub struct Birefringent {
    pub ordinary_ior: IorSpectrum,
    pub extraordinary_ior: IorSpectrum,
    pub ext_ior: IorSpectrum,
    /// Unit optic axis: in the shape's local frame as read, in world space
    /// once [`Birefringent::placed_on`] a shape.
    pub optic_axis: Vec3,
    pub specular_reflectance: Texture,
    pub specular_transmittance: Texture,
    /// The `dielectric` this is when n_o = n_e.
    isotropic: Option<Dielectric>,
}

/// An index parameter: a crystal's name, or what `dielectric` accepts.
fn index_param(props: &Props, name: &str, extraordinary: bool) -> Result<IorSpectrum> {
    let text = props.node.props.iter().find(|p| p.name == name).and_then(|p| match &p.value {
        crate::scene::xml::Value::String(s) => Some(s.clone()),
        _ => None,
    });
    if let Some(s) = text {
        if let Some(ior) = crystal_index(&s, extraordinary) {
            props.string_opt(name)?;
            return Ok(ior);
        }
        if parse_ior_expr(&s).is_none() && crate::bsdf::ior::lookup_ior(&s).is_none() {
            let mut choices = crystal_names();
            choices.extend(crate::bsdf::ior::ior_names());
            return Err(props.error_at(name, format!("unknown index of refraction \"{s}\" for \"{name}\" (give a number, a crystal or a name)")).with_choices(&choices));
        }
    }
    props.ior_spectrum(name, 1.0)
}

impl Birefringent {
    /// Reads the parameters in the table above.
    pub fn from_props(props: &Props, loader: &dyn PluginLoader) -> Result<Birefringent> {
        let ordinary_ior = if props.has("ordinary_ior") { index_param(props, "ordinary_ior", false)? } else { crystal_index("calcite", false).unwrap_or(IorSpectrum::Constant(1.6584)) };
        let extraordinary_ior =
            if props.has("extraordinary_ior") { index_param(props, "extraordinary_ior", true)? } else { crystal_index("calcite", true).unwrap_or(IorSpectrum::Constant(1.4864)) };
        let ext_ior = props.ior_spectrum("ext_ior", AIR)?;
        let axis = props.vec3("optic_axis", Vec3::Z)?;
        let optic_axis = axis.try_normalize().filter(|a| a.is_finite()).ok_or_else(|| props.error_at("optic_axis", "\"optic_axis\" must be a non-zero vector"))?;
        let specular_reflectance = loader.reflectance(props, "specular_reflectance", Rgb::WHITE)?;
        let specular_transmittance = loader.reflectance(props, "specular_transmittance", Rgb::WHITE)?;
        Ok(Birefringent::new(ordinary_ior, extraordinary_ior, ext_ior, optic_axis, specular_reflectance, specular_transmittance))
    }

    pub fn new(
        ordinary_ior: IorSpectrum,
        extraordinary_ior: IorSpectrum,
        ext_ior: IorSpectrum,
        optic_axis: Vec3,
        specular_reflectance: Texture,
        specular_transmittance: Texture,
    ) -> Birefringent {
        let isotropic = (ordinary_ior == extraordinary_ior).then(|| {
            let dispersive = ordinary_ior.is_dispersive() || ext_ior.is_dispersive();
            Dielectric {
                eta: ordinary_ior.nominal() / ext_ior.nominal(),
                dispersion: dispersive.then(|| Box::new(DispersiveInterface { int_ior: ordinary_ior.clone(), ext_ior: ext_ior.clone() })),
                specular_reflectance: specular_reflectance.clone(),
                specular_transmittance: specular_transmittance.clone(),
            }
        });
        Birefringent { ordinary_ior, extraordinary_ior, ext_ior, optic_axis, specular_reflectance, specular_transmittance, isotropic }
    }

    /// A copy for a shape placed by `to_world`: the axis turned into world space.
    pub fn placed_on(&self, to_world: &Transform) -> Birefringent {
        let axis = to_world.vector(self.optic_axis).try_normalize().unwrap_or(self.optic_axis);
        Birefringent { optic_axis: axis, ..self.clone() }
    }

    /// (n_ext, n_o, n_e) at the hero wavelength (spectral modes) or the d line.
    pub fn indices<S: Spectrum>(&self, wl: &S::Wavelengths) -> (f64, f64, f64) {
        let at = |ior: &IorSpectrum| match S::hero_wavelength(wl) {
            Some(lambda) => ior.eval(lambda) as f64,
            None => ior.nominal() as f64,
        };
        (at(&self.ext_ior), at(&self.ordinary_ior), at(&self.extraordinary_ior))
    }
}

impl BsdfModel for Birefringent {
    fn lobes(&self) -> Lobe {
        Lobe::DELTA
    }

    fn has_mueller_model(&self) -> bool {
        true
    }

    fn disperses(&self) -> bool {
        self.ordinary_ior.is_dispersive() || self.extraordinary_ior.is_dispersive() || self.ext_ior.is_dispersive()
    }

    #[inline]
    fn eval<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> S {
        S::zero()
    }

    #[inline]
    fn pdf<S: Spectrum>(&self, _ctx: &BsdfContext, _si: &SurfaceInteraction, _wi: Vec3, _wo: Vec3, _wl: &S::Wavelengths) -> f32 {
        0.0
    }

    fn sample<S: Spectrum>(&self, ctx: &BsdfContext, si: &SurfaceInteraction, wi: Vec3, u: f32, u2: Vec2, wl: &S::Wavelengths) -> Option<BsdfSample<S>> {
        if let Some(d) = &self.isotropic {
            return d.sample(ctx, si, wi, u, u2, wl);
        }
        let (n_ext, n_o, n_e) = self.indices::<S>(wl);
        let axis = si.to_local(self.optic_axis).as_dvec3().try_normalize()?;
        let crystal = Uniaxial { n_ext, n_o, n_e, axis };
        let basis = |d: DVec3| si.to_local(stokes_basis(si.to_world(d.as_vec3()).normalize())).as_dvec3();
        let wi_d = wi.as_dvec3().try_normalize()?;
        let at_wi = match (wi.z > 0.0, ctx.extraordinary) {
            (true, _) => Wave::Outside,
            (false, false) => Wave::Ordinary,
            (false, true) => Wave::Extraordinary,
        };
        // Radiance: the wave sent back along −wi (time reversal) decides the
        // directions; importance: the physical wave arriving along −wi.
        let first = crystal.scatter(at_wi, -wi_d, &basis)?;
        let wanted = |s: &Scattered| {
            let reflects = s.ray.is_some_and(|r| (r.z > 0.0) == (wi.z > 0.0));
            s.ray.is_some() && ctx.wants(if reflects { Lobe::DELTA_REFLECTION } else { Lobe::DELTA_TRANSMISSION })
        };
        let total: f64 = first.out.iter().filter(|s| wanted(s)).map(|s| s.power).sum();
        if !(total > 0.0) {
            return None;
        }
        let mut target = u as f64 * total;
        let mut chosen = None;
        for s in first.out.iter().filter(|s| wanted(s) && s.power > 0.0) {
            chosen = Some(s);
            if target < s.power {
                break;
            }
            target -= s.power;
        }
        let s = chosen?;
        let ray = s.ray?;
        let p = s.power / total;
        let (jones, power, etendue) = match ctx.mode {
            TransportMode::Importance => (s.jones, s.power, 1.0),
            TransportMode::Radiance => {
                // The physical transfer from the chosen wave (arriving along
                // −wo) to the path's wave leaving along wi.
                let back = crystal.scatter(s.wave, -ray, &basis)?;
                let b = back.out.iter().find(|o| o.wave == at_wi)?;
                (b.jones, b.power, s.kappa / first.incident_kappa)
            }
        };
        let wo = ray.as_vec3();
        let reflection = (wo.z > 0.0) == (wi.z > 0.0);
        let scale = if reflection { self.specular_reflectance.eval_spectrum::<S>(si.uv, wl) } else { self.specular_transmittance.eval_spectrum::<S>(si.uv, wl) };
        let weight = if S::POLARIZED {
            S::mueller(jones_to_mueller(jones), scale) * ((etendue / p) as f32)
        } else {
            scale * ((power * etendue / p) as f32)
        };
        let mut lobe = if reflection { Lobe::DELTA_REFLECTION } else { Lobe::DELTA_TRANSMISSION };
        if wo.z < 0.0 && s.wave == Wave::Extraordinary {
            lobe |= Lobe::EXTRAORDINARY;
        }
        let eta = if reflection { 1.0 } else { (s.index / first.incident_index) as f32 };
        Some(BsdfSample { wo, weight, pdf: p as f32, eta, lobe })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::Bsdf;
    use crate::bsdf::fresnel::fresnel_dielectric;
    use crate::bsdf::testing::dummy_interaction;
    use crate::math::Pcg32;
    use crate::math::sampling::square_to_uniform_sphere;
    use crate::spectrum::mueller::{interface_to_canonical, linear_polarizer, specular_reflection};
    use crate::spectrum::Polarized;

    const SODIUM: f32 = 589.3;

    /// The canonical Stokes basis with the local frame as world frame:
    /// `stokes_basis`, made orthogonal to `d` and unit in f64, so that the
    /// tests measure the scattering's own arithmetic and not the rounding
    /// of f32 frames (with those, the flux sums were off by up to 1e-6).
    fn canonical(d: DVec3) -> DVec3 {
        let w = d.normalize();
        let b = stokes_basis(w.as_vec3()).as_dvec3();
        (b - w * b.dot(w)).normalize()
    }

    fn calcite(axis: DVec3) -> Uniaxial {
        let (o, e) = (crystal_index("calcite", false).unwrap(), crystal_index("calcite", true).unwrap());
        Uniaxial { n_ext: 1.0, n_o: o.eval(SODIUM) as f64, n_e: e.eval(SODIUM) as f64, axis: axis.normalize() }
    }

    fn random_dir(rng: &mut Pcg32) -> DVec3 {
        square_to_uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32())).as_dvec3().normalize()
    }

    #[test]
    fn named_crystals_match_the_handbook_indices() {
        // Sodium D line values (CRC Handbook; Hecht, Optics, table 8.1;
        // Hobbs for ice): (name, n_o, n_e, tolerance).
        for (name, n_o, n_e, tol) in [
            ("calcite", 1.6584, 1.4864, 3e-4),
            ("quartz", 1.5443, 1.5534, 3e-4),
            ("sapphire", 1.768, 1.760, 1e-3),
            ("rutile", 2.613, 2.909, 2e-3),
            ("ice", 1.3090, 1.3104, 1e-6),
        ] {
            let (o, e) = (crystal_index(name, false).unwrap().eval(SODIUM), crystal_index(name, true).unwrap().eval(SODIUM));
            assert!((o - n_o).abs() < tol && (e - n_e).abs() < tol, "{name}: n_o {o} vs {n_o}, n_e {e} vs {n_e}");
            if name != "ice" {
                let ior = crystal_index(name, false).unwrap();
                assert!(ior.eval(450.0) > ior.eval(650.0), "{name}: normal dispersion");
            }
        }
        assert!(crystal_index("Calcite ", true).is_some() && crystal_index("glass", false).is_none());
    }

    #[test]
    fn each_wave_obeys_its_snell_law_and_the_extraordinary_index_formula() {
        let mut rng = Pcg32::new(7, 3);
        for _ in 0..2000 {
            let c = calcite(random_dir(&mut rng));
            let mut d = random_dir(&mut rng);
            d.z = -d.z.abs().max(0.05);
            let d = d.normalize();
            let Some(out) = c.scatter(Wave::Outside, d, &canonical) else { panic!("outside incidence always scatters") };
            let kt = DVec3::new(d.x, d.y, 0.0) * c.n_ext;
            for s in &out.out {
                let ray = s.ray.expect("from air nothing is totally reflected");
                let k = c.wave_vector(s.wave, ray);
                // The tangential wave vector is shared by all waves (Snell).
                assert!((DVec3::new(k.x, k.y, 0.0) - kt).length() < 1e-9, "{:?}: {k} vs {kt}", s.wave);
                assert!((k.length() - s.index).abs() < 1e-9);
                match s.wave {
                    Wave::Outside => assert!((ray - DVec3::new(d.x, d.y, -d.z)).length() < 1e-9, "mirror direction"),
                    Wave::Ordinary => assert!((s.index - c.n_o).abs() < 1e-12 && ray.z < 0.0),
                    Wave::Extraordinary => {
                        let cos = k.normalize().dot(c.axis);
                        let n = c.extraordinary_index(cos);
                        assert!((s.index - n).abs() < 1e-9, "n(θ) {} vs {n}", s.index);
                        assert!(ray.z < 0.0, "the e-ray enters the crystal");
                        // Walk-off: the ray is the ellipsoid's normal, in the plane of k and the axis.
                        assert!(ray.dot(k.cross(c.axis)).abs() < 1e-9);
                    }
                }
            }
        }
    }

    #[test]
    fn walk_off_of_calcite_at_45_degrees_is_the_closed_form() {
        let c = calcite(DVec3::new(1.0, 0.0, 1.0));
        let theta = std::f64::consts::FRAC_PI_4;
        let out = c.scatter(Wave::Outside, -DVec3::Z, &canonical).unwrap();
        let (o, e) = (out.out[1].ray.unwrap(), out.out[2].ray.unwrap());
        assert!((o + DVec3::Z).length() < 1e-12, "the o-ray goes straight: {o}");
        let rho = e.dot(-DVec3::Z).acos();
        let (no2, ne2) = (c.n_o * c.n_o, c.n_e * c.n_e);
        let (s, co) = theta.sin_cos();
        let closed = ((no2 - ne2) * s * co / (ne2 * co * co + no2 * s * s)).atan();
        assert!((rho - closed).abs() < 1e-9, "ρ = {}° vs {}°", rho.to_degrees(), closed.to_degrees());
        assert!((rho.to_degrees() - 6.2).abs() < 0.05, "calcite's walk-off at 45° is 6.2°: {}", rho.to_degrees());
        // The brief's form, tan ρ = (1 − n_o²/n_e²) tanθ / (1 + n_o²/n_e² tan²θ), up to sign.
        let r = no2 / ne2;
        assert!(((1.0 - r) * theta.tan() / (1.0 + r * theta.tan().powi(2))).abs().atan() - rho < 1e-9);
        // For calcite (negative) the ray turns away from the axis: towards +x here.
        assert!(e.x > 0.0);
        // At normal incidence the wave normal is not deviated, and the e index is n(45°).
        assert!((out.out[2].index - c.extraordinary_index(theta.cos())).abs() < 1e-12);
    }

    #[test]
    fn an_axis_along_the_normal_does_not_split_normal_incidence() {
        let c = calcite(DVec3::Z);
        let out = c.scatter(Wave::Outside, -DVec3::Z, &canonical).unwrap();
        let (o, e) = (out.out[1], out.out[2]);
        assert!((o.ray.unwrap() - e.ray.unwrap()).length() < 1e-12 && (o.ray.unwrap() + DVec3::Z).length() < 1e-12);
        assert!((o.index - c.n_o).abs() < 1e-12 && (e.index - c.n_o).abs() < 1e-12, "both indices are n_o: {} {}", o.index, e.index);
        let r = ((c.n_o - 1.0) / (c.n_o + 1.0)).powi(2);
        assert!((out.out[0].power - r).abs() < 1e-12);
        assert!((o.power - 0.5 * (1.0 - r)).abs() < 1e-12 && (e.power - 0.5 * (1.0 - r)).abs() < 1e-12);
    }

    #[test]
    fn flux_is_conserved_per_polarization_including_total_internal_reflection() {
        let mut rng = Pcg32::new(11, 5);
        let mut tir = [0usize; 2];
        for i in 0..3000 {
            let mut c = calcite(random_dir(&mut rng));
            if i % 3 == 1 {
                (c.n_o, c.n_e) = (2.613, 2.909); // rutile: positive, strong
            }
            let d = random_dir(&mut rng);
            for wave in [Wave::Outside, Wave::Ordinary, Wave::Extraordinary] {
                let dd = if wave == Wave::Outside { DVec3::new(d.x, d.y, -d.z.abs().max(0.02)) } else { DVec3::new(d.x, d.y, d.z.abs().max(0.02)) }.normalize();
                let Some(out) = c.scatter(wave, dd, &canonical) else { panic!("{wave:?} {dd}") };
                let total: f64 = out.out.iter().map(|s| s.power).sum();
                assert!((total - 1.0).abs() < 1e-9, "{wave:?} along {dd}: R + T_o + T_e = {total}");
                if wave == Wave::Outside {
                    // Each incident polarisation on its own: the columns' norms add to 1.
                    for col in 0..2 {
                        let t: f64 = out.out.iter().map(|s| s.jones[0][col].norm_sqr() + s.jones[1][col].norm_sqr()).sum();
                        assert!((t - 1.0).abs() < 1e-9, "polarisation {col}: {t}");
                    }
                } else if out.out[2].ray.is_none() {
                    tir[(wave == Wave::Extraordinary) as usize] += 1;
                    assert_eq!(out.out[2].power, 0.0);
                }
                for s in &out.out {
                    let m = jones_to_mueller(s.jones);
                    assert!((m.x_axis.x as f64 - if wave == Wave::Outside { s.power } else { 0.5 * s.power }).abs() < 1e-5);
                }
            }
        }
        assert!(tir[0] > 100 && tir[1] > 100, "total internal reflection of both rays was exercised: {tir:?}");
    }

    #[test]
    fn equal_indices_give_the_dielectric_fresnel_terms_and_mueller_matrices() {
        let mut rng = Pcg32::new(2, 9);
        for _ in 0..500 {
            let eta = 1.5;
            let c = Uniaxial { n_ext: 1.0, n_o: eta, n_e: eta, axis: random_dir(&mut rng) };
            let mut d = random_dir(&mut rng);
            d.z = -d.z.abs().max(0.02);
            let d = d.normalize();
            let out = c.scatter(Wave::Outside, d, &canonical).unwrap();
            let f = fresnel_dielectric(-d.z as f32, eta as f32);
            assert!((out.out[0].power - f.r as f64).abs() < 1e-6);
            assert!((out.out[1].power + out.out[2].power - (1.0 - f.r as f64)).abs() < 1e-6);
            let m = jones_to_mueller(out.out[0].jones);
            let r = out.out[0].ray.unwrap();
            let expected = interface_to_canonical(specular_reflection(-d.z as f32, eta as f32), Vec3::Z, d.as_vec3(), r.as_vec3());
            assert!(m.abs_diff_eq(expected, 2e-5), "{m:?} vs {expected:?}");
        }
    }

    fn crystal_bsdf(n_o: f32, n_e: f32, axis: Vec3) -> Bsdf {
        let white = Texture::constant(Rgb::WHITE);
        Bsdf::Birefringent(Birefringent::new(IorSpectrum::Constant(n_o), IorSpectrum::Constant(n_e), IorSpectrum::Constant(1.0), axis, white.clone(), white))
    }

    #[test]
    fn equal_indices_sample_exactly_as_dielectric() {
        let white = Texture::constant(Rgb::WHITE);
        let glass = Bsdf::Dielectric(Dielectric { eta: 1.5, dispersion: None, specular_reflectance: white.clone(), specular_transmittance: white });
        let crystal = crystal_bsdf(1.5, 1.5, Vec3::new(0.3, 0.2, 1.0));
        let si = dummy_interaction();
        let mut rng = Pcg32::new(4, 4);
        for _ in 0..2000 {
            let wi = random_dir(&mut rng).as_vec3();
            let u = rng.next_f32();
            for ctx in [BsdfContext::RADIANCE, BsdfContext::IMPORTANCE] {
                let a = glass.sample::<Rgb>(&ctx, &si, wi, u, Vec2::ZERO, &());
                let b = crystal.sample::<Rgb>(&ctx, &si, wi, u, Vec2::ZERO, &());
                assert_eq!(format!("{a:?}"), format!("{b:?}"));
                let a = glass.sample::<Polarized<Rgb>>(&ctx, &si, wi, u, Vec2::ZERO, &());
                let b = crystal.sample::<Polarized<Rgb>>(&ctx, &si, wi, u, Vec2::ZERO, &());
                assert_eq!(format!("{a:?}"), format!("{b:?}"));
            }
        }
    }

    /// The top and bottom faces of a slab (normals +z and −z, world = the
    /// top face's local frame).
    fn faces() -> (SurfaceInteraction, SurfaceInteraction) {
        let top = dummy_interaction();
        let mut bottom = top;
        bottom.n = -Vec3::Z;
        bottom.frame = crate::math::Frame::from_normal(-Vec3::Z);
        (top, bottom)
    }

    /// A camera path through a slab from (world) direction `wi` with the
    /// given lobe choice `u` at the top: the product of the two vertices'
    /// weights, the world direction leaving the bottom, whether the path
    /// was an e-ray inside, and the probability of the lobe choices.
    fn slab_path<S: Spectrum<Wavelengths = ()>>(bsdf: &Bsdf, wi: Vec3, u: f32) -> (S, Vec3, bool, f32) {
        let (top, bottom) = faces();
        let ctx = BsdfContext::RADIANCE.with_lobes(Lobe::DELTA_TRANSMISSION);
        let a = bsdf.sample::<S>(&ctx, &top, top.to_local(wi), u, Vec2::ZERO, &()).expect("enters");
        let d = top.to_world(a.wo);
        let b = bsdf.sample::<S>(&ctx.following(a.lobe), &bottom, bottom.to_local(-d), 0.5, Vec2::ZERO, &()).expect("leaves the slab");
        (a.weight * b.weight, bottom.to_world(b.wo), a.lobe.contains(Lobe::EXTRAORDINARY), a.pdf * b.pdf)
    }

    /// The Stokes vector (channel 0) reaching the camera through a slab from
    /// unpolarised light of intensity 1 below it, along the path that
    /// travels as an o- or e-ray inside, and the direction it leaves along.
    fn through_slab(bsdf: &Bsdf, wi: Vec3, extraordinary: bool) -> (Vec4, Vec3) {
        let (m, out, _, p) = (0..100)
            .map(|i| slab_path::<Polarized<Rgb>>(bsdf, wi, (i as f32 + 0.5) / 100.0))
            .find(|p| p.2 == extraordinary)
            .expect("both modes are sampled");
        // Its share of the expected value: the weight times the choice's probability.
        (Vec4::new(m.0[0][0][0], m.0[1][0][0], m.0[2][0][0], m.0[3][0][0]) * p, out)
    }

    #[test]
    fn the_two_images_are_polarized_at_right_angles_malus() {
        let bsdf = crystal_bsdf(1.6584, 1.4864, Vec3::new(1.0, 0.0, 1.0));
        for wi in [Vec3::Z, Vec3::new(0.2, -0.1, 1.0).normalize()] {
            let (o, wo_o) = through_slab(&bsdf, wi, false);
            let (e, wo_e) = through_slab(&bsdf, wi, true);
            // A parallel slab: both leave parallel to the incident direction.
            assert!((wo_o + wi).length() < 1e-4 && (wo_e + wi).length() < 1e-4, "{wo_o} {wo_e}");
            // Each image is fully polarised, at right angles to the other.
            for s in [o, e] {
                assert!(((s.y * s.y + s.z * s.z + s.w * s.w).sqrt() / s.x - 1.0).abs() < 1e-3, "{s:?}");
            }
            let (ao, ae) = (0.5 * o.z.atan2(o.y), 0.5 * e.z.atan2(e.y));
            let diff = (ao - ae).rem_euclid(std::f32::consts::PI);
            // Exactly at normal incidence; at 13° the exit face's unequal s/p
            // transmittances turn each by a few mrad.
            let normal = wi == Vec3::Z;
            let tol = if normal { 1e-4 } else { 1e-2 };
            assert!((diff - std::f32::consts::FRAC_PI_2).abs() < tol, "o at {ao}, e at {ae}");
            // A polarizer along one extinguishes it below 1e-3 of the other; Malus in between.
            for (s, angle, other) in [(o, ao, e), (e, ae, o)] {
                let passed = (linear_polarizer(angle) * s).x;
                assert!((passed - s.x).abs() < 1e-3 * s.x);
                let blocked = (linear_polarizer(angle) * other).x;
                assert!(blocked < if normal { 1e-6 } else { 1e-3 } * other.x, "{blocked} vs {}", other.x);
                for t in [0.3f32, 0.7, 1.1] {
                    let malus = (linear_polarizer(angle + t) * s).x;
                    assert!((malus - s.x * t.cos().powi(2)).abs() < 2e-3 * s.x);
                }
            }
            // Unpolarised light: each image carries half of what crosses both faces.
            let (no, ne) = (1.6584f32, 1.4864f32);
            let t_total = o.x + e.x;
            assert!(t_total > 0.8 && t_total < 1.0);
            if wi == Vec3::Z {
                // Normal incidence: each mode sees its own index n_o or n(45°) on both faces.
                let n45 = 1.0 / (0.5 / (no * no) + 0.5 / (ne * ne)).sqrt();
                let t = |n: f32| 1.0 - ((n - 1.0) / (n + 1.0)).powi(2);
                assert!((o.x - 0.5 * t(no) * t(no)).abs() < 1e-5, "{} vs {}", o.x, 0.5 * t(no) * t(no));
                assert!((e.x - 0.5 * t(n45) * t(n45)).abs() < 1e-5, "{} vs {}", e.x, 0.5 * t(n45) * t(n45));
            }
        }
    }

    #[test]
    fn unpolarized_modes_split_with_the_same_intensities() {
        // RGB: the expected through-slab value equals the polarized mode's S0.
        let bsdf = crystal_bsdf(1.6584, 1.4864, Vec3::new(1.0, 0.0, 1.0));
        let wi = Vec3::new(0.1, 0.2, 1.0).normalize();
        let n = 20_000;
        let mut sum = 0.0f64;
        for i in 0..n {
            let (w, out, _, _) = slab_path::<Rgb>(&bsdf, wi, (i as f32 + 0.5) / n as f32);
            assert!((out + wi).length() < 1e-4);
            sum += w[0] as f64;
        }
        let expected = through_slab(&bsdf, wi, false).0.x + through_slab(&bsdf, wi, true).0.x;
        assert!((sum / n as f64 - expected as f64).abs() < 2e-4, "{} vs {expected}", sum / n as f64);
    }

    #[test]
    fn reflection_is_sampled_by_its_fresnel_weight() {
        let bsdf = crystal_bsdf(1.6584, 1.4864, Vec3::new(0.2, 0.5, 1.0));
        let si = dummy_interaction();
        let c = Uniaxial { n_ext: 1.0, n_o: 1.6584, n_e: 1.4864, axis: si.to_local(Vec3::new(0.2, 0.5, 1.0).normalize()).as_dvec3() };
        let wi = Vec3::new(0.5, 0.1, 0.6).normalize();
        let out = c.scatter(Wave::Outside, -wi.as_dvec3(), &canonical).unwrap();
        let n = 100_000;
        let mut counts = [0usize; 3];
        let mut rng = Pcg32::new(1, 1);
        for _ in 0..n {
            let s = bsdf.sample::<Rgb>(&BsdfContext::RADIANCE, &si, wi, rng.next_f32(), Vec2::ZERO, &()).unwrap();
            let k = if s.lobe.contains(Lobe::DELTA_REFLECTION) { 0 } else if s.lobe.contains(Lobe::EXTRAORDINARY) { 2 } else { 1 };
            counts[k] += 1;
            // Each sample's direction is that wave's ray.
            assert!((s.wo.as_dvec3() - out.out[k].ray.unwrap()).length() < 1e-5);
            assert!((s.pdf as f64 - out.out[k].power).abs() < 1e-5);
        }
        for k in 0..3 {
            let p = out.out[k].power;
            let sigma = (p * (1.0 - p) / n as f64).sqrt();
            assert!((counts[k] as f64 / n as f64 - p).abs() < 5.0 * sigma, "lobe {k}: {} vs {p}", counts[k] as f64 / n as f64);
        }
    }

    #[test]
    fn spectral_modes_disperse_each_index() {
        use crate::spectrum::Sampled;
        let white = Texture::constant(Rgb::WHITE);
        let (o, e) = (crystal_index("calcite", false).unwrap(), crystal_index("calcite", true).unwrap());
        let b = Birefringent::new(o.clone(), e.clone(), IorSpectrum::Constant(1.0), Vec3::new(1.0, 0.0, 1.0), white.clone(), white.clone());
        assert!(b.disperses());
        let constant = Birefringent::new(IorSpectrum::Constant(1.66), IorSpectrum::Constant(1.49), IorSpectrum::Constant(1.0), Vec3::Z, white.clone(), white);
        assert!(!constant.disperses());
        // RGB uses the d line; spectral modes the hero wavelength, and the
        // walk-off at normal incidence follows each index at that wavelength.
        assert_eq!(b.indices::<Rgb>(&()), (1.0, o.nominal() as f64, e.nominal() as f64));
        let si = dummy_interaction();
        let ctx = BsdfContext::RADIANCE.with_lobes(Lobe::DELTA_TRANSMISSION);
        let mut walk_offs = vec![];
        for u in [0.05f32, 0.5, 0.95] {
            let wl = Sampled::sample_wavelengths(u);
            let lambda = Sampled::hero_wavelength(&wl).unwrap();
            let (_, n_o, n_e) = b.indices::<Sampled>(&wl);
            assert_eq!((n_o as f32, n_e as f32), (o.eval(lambda), e.eval(lambda)));
            let s = (0..50)
                .filter_map(|i| Bsdf::Birefringent(b.clone()).sample::<Sampled>(&ctx, &si, si.to_local(Vec3::Z), (i as f32 + 0.5) / 50.0, Vec2::ZERO, &wl))
                .find(|s| s.lobe.contains(Lobe::EXTRAORDINARY))
                .unwrap();
            let rho = si.to_world(s.wo).dot(-Vec3::Z).acos() as f64;
            let closed = ((n_o * n_o - n_e * n_e) * 0.5 / (0.5 * (n_o * n_o + n_e * n_e))).atan();
            assert!((rho - closed).abs() < 1e-5, "{lambda} nm: {rho} vs {closed}");
            walk_offs.push((lambda, rho));
        }
        walk_offs.sort_by(|a, b| a.0.total_cmp(&b.0));
        assert!(walk_offs[0].1 > walk_offs[2].1, "calcite's birefringence falls with the wavelength: {walk_offs:?}");
    }

    #[test]
    fn radiance_scaling_is_reciprocal_across_the_interface() {
        // Entering and leaving along the same e-wave, the étendue factors cancel.
        let c = calcite(DVec3::new(0.3, 0.7, 0.5));
        let mut rng = Pcg32::new(3, 3);
        for _ in 0..200 {
            let mut d = random_dir(&mut rng);
            d.z = -d.z.abs().max(0.05);
            let d = d.normalize();
            let inn = c.scatter(Wave::Outside, d, &canonical).unwrap();
            let e = inn.out[2];
            let out = c.scatter(Wave::Extraordinary, -e.ray.unwrap(), &canonical).unwrap();
            assert!((out.out[2].ray.unwrap() + d).length() < 1e-9, "time reversal retraces the ray");
            assert!((e.kappa * out.incident_kappa.recip() - 1.0).abs() < 1e-9);
            // Flux reciprocity: unpolarised → e equals half of e → outside.
            assert!((e.power - 0.5 * out.out[2].power).abs() < 1e-6, "{} vs {}", e.power, 0.5 * out.out[2].power);
            // The ellipsoid's κ against a numerical Jacobian d²K / (cos θ_s dω_s).
            let k = c.wave_vector(Wave::Extraordinary, e.ray.unwrap());
            let (t1, t2) = (DVec3::X * 1e-5, DVec3::Y * 1e-5);
            let ray_at = |kt: DVec3| {
                let dd = (kt + DVec3::Z * -(1.0 - kt.length_squared()).max(0.0).sqrt()).normalize();
                c.scatter(Wave::Outside, dd, &canonical).unwrap().out[2].ray.unwrap()
            };
            let kt = DVec3::new(k.x, k.y, 0.0);
            let (s0, s1, s2) = (ray_at(kt), ray_at(kt + t1), ray_at(kt + t2));
            let domega = (s1 - s0).cross(s2 - s0).length();
            let jac = 1e-10 / (domega * s0.z.abs());
            assert!((jac * e.kappa - 1.0).abs() < 1e-3, "d²K/(cos dω) = {jac} vs 1/κ = {}", 1.0 / e.kappa);
        }
    }
}
