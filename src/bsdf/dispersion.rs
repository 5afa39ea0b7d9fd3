//! Wavelength-dependent indices of refraction: dispersion.
//!
//! The seed: the index of refraction "depends on the wavelength", which
//! splits white light in a prism and makes rainbows. An [`IorSpectrum`] gives
//! η(λ) for λ in nanometres (vacuum wavelength), by one of
//!
//! - **Sellmeier**: η² = 1 + Σᵢ Bᵢ λ² / (λ² − Cᵢ), λ in µm, Cᵢ in µm² (the
//!   form glass catalogues and refractiveindex.info publish);
//! - **Cauchy**: η = A + B / λ², λ in µm;
//! - **tabulated**: (λ, η) pairs, linearly interpolated, clamped at the ends;
//! - **constant**: no dispersion (Mitsuba's scalar `int_ior` / `ext_ior`).
//!
//! Named dispersive media (coefficients from the cited measurements):
//!
//! | name | formula | source |
//! |---|---|---|
//! | `bk7` | Sellmeier, 3 terms | Schott N-BK7 data sheet |
//! | `fused silica` | Sellmeier, 3 terms | I. H. Malitson, JOSA 55, 1205 (1965) |
//! | `sf11` | Sellmeier, 3 terms | Schott SF11 data sheet |
//! | `water` | Sellmeier, 4 terms, 20 °C | M. Daimon, A. Masumura, Appl. Opt. 46, 3811 (2007) |
//! | `diamond` | Sellmeier, 2 terms | F. Peter, Z. Phys. 15, 358 (1923) |
//!
//! In RGB mode a dispersive medium uses its index at the helium d line
//! (587.56 nm), the wavelength glass catalogues quote as n_d.
//!
//! ## In scene files
//!
//! Mitsuba 3 has no dispersive dielectric, so this syntax is Snell's own. A
//! plain number or name in `int_ior` / `ext_ior` keeps Mitsuba's meaning (a
//! constant: `bk7` is 1.5046, as in Mitsuba), so shared files render alike;
//! dispersion is asked for explicitly with a string of one of these forms:
//!
//! ```xml
//! <string name="int_ior" value="sellmeier:bk7"/>       <!-- a named medium above -->
//! <string name="int_ior" value="sellmeier(1.03961212, 0.231792344, 1.01046945;
//!                                         0.00600069867, 0.0200179144, 103.560653)"/>
//! <string name="int_ior" value="cauchy(1.5046, 0.00420)"/>   <!-- A, B (µm²) -->
//! ```
//!
//! `sellmeier(B₁, …, Bₙ; C₁, …, Cₙ)` takes one to six terms, C in µm².

/// The helium d line (nm): where catalogues quote n_d, and the index a
/// dispersive medium has in RGB mode.
pub const D_LINE_NM: f32 = 587.56;

/// η(λ) of a dielectric.
#[derive(Clone, Debug, PartialEq)]
pub enum IorSpectrum {
    Constant(f32),
    /// η² = 1 + Σ b[i] λ² / (λ² − c[i]), λ in µm.
    Sellmeier { b: Vec<f64>, c: Vec<f64> },
    /// η = a + b / λ², λ in µm.
    Cauchy { a: f64, b: f64 },
    /// (λ nm, η) pairs with increasing λ.
    Tabulated(Vec<(f32, f32)>),
}

/// The two media of a dispersive interface (`dielectric` with a dispersive
/// `int_ior` or `ext_ior`).
#[derive(Clone, Debug, PartialEq)]
pub struct DispersiveInterface {
    pub int_ior: IorSpectrum,
    pub ext_ior: IorSpectrum,
}

impl DispersiveInterface {
    /// Relative index int/ext at vacuum wavelength `lambda` (nm).
    pub fn eta(&self, lambda: f32) -> f32 {
        self.int_ior.eval(lambda) / self.ext_ior.eval(lambda)
    }
}

/// Named dispersive media: (name, Sellmeier B, Sellmeier C in µm²).
const NAMED: &[(&str, &[f64], &[f64])] = &[
    ("bk7", &[1.039_612_12, 0.231_792_344, 1.010_469_45], &[0.006_000_698_67, 0.020_017_914_4, 103.560_653]),
    (
        "fused silica",
        &[0.696_166_3, 0.407_942_6, 0.897_479_4],
        // Malitson gives the resonance wavelengths 0.0684043, 0.1162414, 9.896161 µm.
        &[0.004_679_148_26, 0.013_512_063_1, 97.934_002_5],
    ),
    ("sf11", &[1.737_596_95, 0.313_747_346, 1.898_781_01], &[0.013_188_707, 0.062_306_814_2, 155.236_29]),
    (
        "water",
        &[5.684_027_565e-1, 1.726_177_391e-1, 2.086_189_578e-2, 1.130_748_688e-1],
        &[5.101_829_712e-3, 1.821_153_936e-2, 2.620_722_293e-2, 1.069_792_721e1],
    ),
    ("diamond", &[0.3306, 4.3356], &[0.030_625, 0.011_236]),
];

/// The named dispersive medium `name` (case-insensitive).
pub fn named_dispersive(name: &str) -> Option<IorSpectrum> {
    let lower = name.trim().to_ascii_lowercase();
    NAMED.iter().find(|(n, _, _)| *n == lower).map(|(_, b, c)| IorSpectrum::Sellmeier { b: b.to_vec(), c: c.to_vec() })
}

/// The valid names, for error messages.
pub fn dispersive_names() -> Vec<&'static str> {
    NAMED.iter().map(|(n, _, _)| *n).collect()
}

/// Parses the dispersive forms of an `int_ior` / `ext_ior` string (see the
/// module documentation). `None`: not a dispersive form (the caller treats
/// it as a constant's name); `Some(Err)`: a dispersive form with a mistake.
pub fn parse_ior_expr(text: &str) -> Option<Result<IorSpectrum, String>> {
    let t = text.trim();
    let lower = t.to_ascii_lowercase();
    if let Some(name) = lower.strip_prefix("sellmeier:") {
        return Some(named_dispersive(name).ok_or_else(|| {
            format!("unknown dispersive medium \"{}\" (valid: {})", name.trim(), dispersive_names().join(", "))
        }));
    }
    let (kind, args) = if let Some(rest) = lower.strip_prefix("sellmeier") {
        ("sellmeier", rest)
    } else if let Some(rest) = lower.strip_prefix("cauchy") {
        ("cauchy", rest)
    } else {
        return None;
    };
    let Some(inner) = args.trim().strip_prefix('(').and_then(|a| a.strip_suffix(')')) else {
        return Some(Err(format!("expected {kind}(…) with the coefficients in parentheses")));
    };
    let numbers = |part: &str| -> Result<Vec<f64>, String> {
        part.split(',')
            .map(|x| {
                let x = x.trim();
                x.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| format!("\"{x}\" is not a number"))
            })
            .collect()
    };
    let result = match kind {
        "sellmeier" => {
            let Some((b, c)) = inner.split_once(';') else {
                return Some(Err("sellmeier(B₁, …, Bₙ; C₁, …, Cₙ) needs a ';' between the B and the C coefficients".into()));
            };
            match (numbers(b), numbers(c)) {
                (Ok(b), Ok(c)) if b.len() == c.len() && (1..=6).contains(&b.len()) => Ok(IorSpectrum::Sellmeier { b, c }),
                (Ok(b), Ok(c)) => Err(format!("sellmeier needs as many B as C coefficients, 1 to 6 each (got {} and {})", b.len(), c.len())),
                (Err(e), _) | (_, Err(e)) => Err(e),
            }
        }
        _ => match numbers(inner) {
            Ok(v) if v.len() == 2 => Ok(IorSpectrum::Cauchy { a: v[0], b: v[1] }),
            Ok(v) => Err(format!("cauchy(A, B) needs 2 coefficients, not {}", v.len())),
            Err(e) => Err(e),
        },
    };
    Some(result.and_then(|ior| ior.check_visible().map(|()| ior)))
}

impl IorSpectrum {
    /// η at vacuum wavelength `lambda` (nm).
    pub fn eval(&self, lambda: f32) -> f32 {
        let um = lambda as f64 * 1e-3;
        let um2 = um * um;
        match self {
            IorSpectrum::Constant(eta) => *eta,
            IorSpectrum::Sellmeier { b, c } => {
                let n2 = 1.0 + b.iter().zip(c).map(|(b, c)| b * um2 / (um2 - c)).sum::<f64>();
                n2.max(0.0).sqrt() as f32
            }
            IorSpectrum::Cauchy { a, b } => (a + b / um2) as f32,
            IorSpectrum::Tabulated(pairs) => {
                let Some(&(l0, n0)) = pairs.first() else { return 1.0 };
                if lambda <= l0 {
                    return n0;
                }
                for w in pairs.windows(2) {
                    let ((la, na), (lb, nb)) = (w[0], w[1]);
                    if lambda <= lb {
                        let t = if lb > la { (lambda - la) / (lb - la) } else { 0.0 };
                        return na + t * (nb - na);
                    }
                }
                pairs.last().map_or(n0, |p| p.1)
            }
        }
    }

    /// Whether η changes with the wavelength.
    pub fn is_dispersive(&self) -> bool {
        !matches!(self, IorSpectrum::Constant(_))
    }

    /// The single index used where one wavelength stands for all (RGB mode).
    pub fn nominal(&self) -> f32 {
        self.eval(D_LINE_NM)
    }

    /// Checks the medium is physical over the visible range (η ≥ 1 would be
    /// too strict: relative indices below one are legitimate; this demands
    /// a finite, positive η), for the loader's error messages.
    pub fn check_visible(&self) -> Result<(), String> {
        for i in 0..=47 {
            let lambda = 360.0 + 10.0 * i as f32;
            let eta = self.eval(lambda);
            if !(eta.is_finite() && eta > 0.0) {
                return Err(format!("index of refraction is {eta} at {lambda} nm"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::fresnel::{fresnel_dielectric, refract};
    use crate::math::Frame;
    use glam::Vec3;

    /// Fraunhofer lines (nm) at which catalogues quote n_F, n_d, n_C.
    const F_LINE: f32 = 486.13;
    const C_LINE: f32 = 656.27;

    #[test]
    fn catalogue_indices() {
        // (medium, n_d, Abbe number V_d = (n_d − 1)/(n_F − n_C), tolerances):
        // Schott's N-BK7 and SF11 data sheets, Heraeus/Malitson for fused
        // silica, and the commonly quoted values for water (20 °C) and diamond.
        let cases = [
            ("bk7", 1.516_80, 64.17, 2e-5, 0.05),
            ("sf11", 1.784_72, 25.68, 2e-5, 0.05),
            ("fused silica", 1.458_46, 67.82, 2e-5, 0.05),
            ("water", 1.333_0, 55.7, 5e-4, 0.5),
            ("diamond", 2.417_5, 55.3, 5e-4, 0.5),
        ];
        for (name, nd, vd, tol_n, tol_v) in cases {
            let ior = named_dispersive(name).unwrap_or_else(|| panic!("{name} missing"));
            let (nf, n_d, nc) = (ior.eval(F_LINE), ior.eval(D_LINE_NM), ior.eval(C_LINE));
            assert!((n_d - nd).abs() < tol_n, "{name}: n_d {n_d} vs {nd}");
            let abbe = (n_d - 1.0) / (nf - nc);
            assert!((abbe - vd).abs() < tol_v, "{name}: V_d {abbe} vs {vd}");
            assert_eq!(ior.nominal(), n_d);
            // Normal dispersion: η falls with the wavelength.
            assert!(ior.eval(400.0) > ior.eval(550.0) && ior.eval(550.0) > ior.eval(700.0), "{name}");
            assert!(ior.check_visible().is_ok());
        }
        // N-BK7's data sheet also gives n_F and n_C directly.
        let bk7 = named_dispersive("BK7").unwrap_or_else(|| panic!("bk7 missing"));
        assert!((bk7.eval(F_LINE) - 1.522_38).abs() < 2e-5 && (bk7.eval(C_LINE) - 1.514_32).abs() < 2e-5);
        assert!(named_dispersive("flint").is_none());
        assert_eq!(dispersive_names().len(), 5);
    }

    #[test]
    fn scene_file_forms() {
        let named = parse_ior_expr(" Sellmeier:BK7 ");
        assert_eq!(named, Some(Ok(named_dispersive("bk7").unwrap_or_else(|| panic!()))));
        let custom = parse_ior_expr("sellmeier(1.03961212, 0.231792344, 1.01046945; 0.00600069867, 0.0200179144, 103.560653)");
        match custom {
            Some(Ok(ior)) => assert!((ior.nominal() - 1.5168).abs() < 1e-4),
            other => panic!("{other:?}"),
        }
        assert_eq!(parse_ior_expr("cauchy(1.5, 0.004)"), Some(Ok(IorSpectrum::Cauchy { a: 1.5, b: 0.004 })));
        // Not dispersive forms: left to the constant names.
        assert_eq!(parse_ior_expr("bk7"), None);
        assert_eq!(parse_ior_expr("water"), None);
        // Mistakes are errors that say what is wrong.
        for (bad, says) in [
            ("sellmeier:flint", "unknown dispersive medium"),
            ("sellmeier(1, 2; 0.1)", "as many B as C"),
            ("sellmeier(1, 2, 0.1)", "';'"),
            ("sellmeier 1; 2", "parentheses"),
            ("cauchy(1.5)", "2 coefficients"),
            ("cauchy(1.5, x)", "not a number"),
            ("cauchy(-1.5, 0)", "index of refraction is"),
        ] {
            match parse_ior_expr(bad) {
                Some(Err(e)) => assert!(e.contains(says), "{bad}: {e}"),
                other => panic!("{bad}: {other:?}"),
            }
        }
    }

    #[test]
    fn cauchy_tabulated_and_constant() {
        let c = IorSpectrum::Cauchy { a: 1.5046, b: 0.00420 };
        assert!((c.eval(500.0) - (1.5046 + 0.0042 / 0.25) as f32).abs() < 1e-6);
        let t = IorSpectrum::Tabulated(vec![(400.0, 1.6), (600.0, 1.5), (800.0, 1.45)]);
        assert_eq!(t.eval(300.0), 1.6);
        assert!((t.eval(500.0) - 1.55).abs() < 1e-6);
        assert!((t.eval(700.0) - 1.475).abs() < 1e-6);
        assert_eq!(t.eval(900.0), 1.45);
        assert!(t.is_dispersive() && !IorSpectrum::Constant(1.5).is_dispersive());
        assert_eq!(IorSpectrum::Constant(1.5).eval(400.0), 1.5);
        assert!(IorSpectrum::Sellmeier { b: vec![1.0], c: vec![0.3] }.check_visible().is_err());
    }

    /// Sends a ray of direction `d` through a smooth interface with outward
    /// normal `n` between a medium of index `eta` (inside) and vacuum, using
    /// the BSDF's Fresnel and refraction code in the local frame. `None` under
    /// total internal reflection.
    fn refract_world(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
        let frame = Frame::from_normal(n);
        let wi = frame.to_local(-d);
        let f = fresnel_dielectric(wi.z, eta);
        if f.total_internal_reflection() {
            return None;
        }
        Some(frame.to_world(refract(wi, f.cos_t, f.eta_ti)).normalize())
    }

    /// Deviation (radians) of a ray entering a prism of apex angle `apex`
    /// (apex up, faces symmetric about the y axis, in the xy plane) at
    /// incidence angle `theta` on the left face.
    fn prism_deviation(apex: f32, eta: f32, theta: f32) -> Option<f32> {
        let h = 0.5 * apex;
        // Outward normals of the left and right faces.
        let n1 = Vec3::new(-h.cos(), h.sin(), 0.0);
        let n2 = Vec3::new(h.cos(), h.sin(), 0.0);
        // Incoming direction: angle theta to -n1, rotated towards the base.
        let inward = -n1;
        let tangent = Vec3::new(-n1.y, n1.x, 0.0);
        let d_in = (inward * theta.cos() - tangent * theta.sin()).normalize();
        let d_mid = refract_world(d_in, n1, eta)?;
        let d_out = refract_world(d_mid, n2, eta)?;
        Some(d_in.dot(d_out).clamp(-1.0, 1.0).acos())
    }

    #[test]
    fn prism_minimum_deviation_matches_the_closed_form() {
        // A 60° BK7 prism: the least deviation over all incidence angles is
        // D = 2 asin(η sin(A/2)) − A, reached on the symmetric path.
        let apex = 60f32.to_radians();
        let bk7 = named_dispersive("bk7").unwrap_or_else(|| panic!("bk7 missing"));
        let mut previous = None;
        for lambda in [F_LINE, D_LINE_NM, C_LINE] {
            let eta = bk7.eval(lambda);
            let closed = 2.0 * (eta * (0.5 * apex).sin()).asin() - apex;
            // Scan incidence angles finely and take the least deviation.
            let min = (0..=20_000)
                .filter_map(|i| prism_deviation(apex, eta, (20.0 + 60.0 * i as f32 / 20_000.0).to_radians()))
                .fold(f32::INFINITY, f32::min);
            assert!((min - closed).abs() < 2e-5, "{lambda} nm: traced {} deg, closed form {} deg", min.to_degrees(), closed.to_degrees());
            // The symmetric incidence asin(η sin(A/2)) gives it exactly.
            let sym = prism_deviation(apex, eta, (eta * (0.5 * apex).sin()).asin()).unwrap_or(f32::NAN);
            assert!((sym - closed).abs() < 2e-5, "{lambda} nm: symmetric {sym} vs {closed}");
            // Blue bends more than red.
            if let Some(p) = previous {
                assert!(closed < p, "deviation must fall with wavelength");
            }
            previous = Some(closed);
        }
        // The catalogue's angular spread between F and C for 60° BK7 is about 0.8°.
        let spread = [F_LINE, C_LINE].map(|l| 2.0 * (bk7.eval(l) * (0.5 * apex).sin()).asin() - apex);
        let spread_deg = (spread[0] - spread[1]).to_degrees();
        assert!((0.7..0.9).contains(&spread_deg), "F–C spread {spread_deg}°");
    }
}
