//! Named indices of refraction of dielectrics, for `int_ior` / `ext_ior`.
//!
//! The names Mitsuba 3 accepts, with its values (sodium D line, 589 nm, at
//! room temperature, from standard tables such as the CRC Handbook of
//! Chemistry and Physics), plus the names of the seed's table that Mitsuba
//! lacks ("ice", "crown glass", "air at stp"). Names are matched without
//! regard to case.

/// (name, η) pairs, in the order shown to users.
pub const NAMED_IORS: &[(&str, f32)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000_036),
    ("hydrogen", 1.000_132),
    ("air", 1.000_277),
    ("air at stp", 1.000_29),
    ("carbon dioxide", 1.000_45),
    ("water", 1.333),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.520_45),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.47),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("crown glass", 1.52),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.575),
    ("diamond", 2.419),
];

/// The index of refraction called `name`, if it is known.
pub fn lookup_ior(name: &str) -> Option<f32> {
    let lower = name.trim().to_ascii_lowercase();
    NAMED_IORS.iter().find(|(n, _)| *n == lower).map(|&(_, v)| v)
}

/// The valid names, for error messages.
pub fn ior_names() -> Vec<&'static str> {
    NAMED_IORS.iter().map(|&(n, _)| n).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed_table_names_resolve() {
        // The seed's table: vacuum 1, air 1.00029, ice 1.31, water 1.33, crown glass 1.52–1.65, diamond 2.417.
        for (name, seed_value, tol) in
            [("vacuum", 1.0, 0.0), ("air", 1.00029, 2e-5), ("ice", 1.31, 0.0), ("water", 1.33, 0.004), ("crown glass", 1.52, 0.0), ("diamond", 2.417, 0.003)]
        {
            let v = lookup_ior(name).unwrap_or_else(|| panic!("{name} missing"));
            assert!((v - seed_value).abs() <= tol + 1e-6, "{name}: {v} vs seed {seed_value}");
        }
        assert_eq!(lookup_ior("BK7"), Some(1.5046));
        assert_eq!(lookup_ior("Fused Quartz"), Some(1.458));
        assert_eq!(lookup_ior("unobtainium"), None);
    }
}
