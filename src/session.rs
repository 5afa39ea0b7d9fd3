//! The library's front door: what the command line, the Python package and
//! the preview server all call to render a loaded scene — the choice of
//! [`Mode`] (what a light path carries), the checks that a scene can be
//! rendered in it, the spectral warm-up, and the pass loop with its callback.

use crate::film::{FilmState, Image};
use crate::integrator::Integrator;
use crate::render::{PassReport, RenderOptions, RenderStats, render_passes, render_progressive};
use crate::scene::Scene;
use crate::spectrum::{Polarized, Rgb, Sampled};

/// What a light path carries: RGB triples (as Mitsuba's `*_rgb` variants),
/// four sampled wavelengths (`*_spectral`; needed for dispersion), or either
/// with a Mueller matrix per channel (`*_polarized`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    Rgb,
    Spectral,
    RgbPolarized,
    SpectralPolarized,
}

impl Mode {
    pub const ALL: [Mode; 4] = [Mode::Rgb, Mode::Spectral, Mode::RgbPolarized, Mode::SpectralPolarized];

    /// The name the command line and Python use (`rgb`, `spectral`,
    /// `rgb-polarized`, `spectral-polarized`).
    pub fn name(self) -> &'static str {
        match self {
            Mode::Rgb => "rgb",
            Mode::Spectral => "spectral",
            Mode::RgbPolarized => "rgb-polarized",
            Mode::SpectralPolarized => "spectral-polarized",
        }
    }

    /// The mode named `name` (also accepting `_` for `-`), or an error that
    /// lists the valid names.
    pub fn from_name(name: &str) -> anyhow::Result<Mode> {
        let wanted = name.trim().to_ascii_lowercase().replace('_', "-");
        Mode::ALL.into_iter().find(|m| m.name() == wanted).ok_or_else(|| {
            let names: Vec<&str> = Mode::ALL.iter().map(|m| m.name()).collect();
            anyhow::anyhow!("unknown mode \"{name}\"; the modes are {}", names.join(", "))
        })
    }

    pub fn polarized(self) -> bool {
        matches!(self, Mode::RgbPolarized | Mode::SpectralPolarized)
    }

    pub fn spectral(self) -> bool {
        matches!(self, Mode::Spectral | Mode::SpectralPolarized)
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Checks that `scene` can be rendered in `mode` and does the mode's one-off
/// work (fitting the RGB uplift table for the spectral modes), so that render
/// time excludes it. `what` names the scene in errors (its file).
pub fn prepare(scene: &Scene, mode: Mode, what: &str) -> anyhow::Result<()> {
    if mode.polarized() && matches!(scene.integrator, Integrator::Particle(_)) {
        anyhow::bail!(
            "{what}: the polarized modes need a camera-path integrator (path or direct); particle tracing (ptracer) does not carry polarization"
        );
    }
    if mode.polarized() && matches!(scene.integrator, Integrator::Bdpt(_)) {
        anyhow::bail!("{what}: the polarized modes need a camera-path integrator (path or direct); bdpt renders in the rgb and spectral modes only");
    }
    if mode.polarized() && matches!(scene.integrator, Integrator::Vcm(_)) {
        anyhow::bail!("{what}: the polarized modes need a camera-path integrator (path or direct); vcm renders in the rgb and spectral modes only");
    }
    if mode.polarized() && matches!(scene.integrator, Integrator::Sppm(_)) {
        anyhow::bail!("{what}: the polarized modes need a camera-path integrator (path or direct); photon mapping (sppm) does not carry polarization");
    }
    if mode.polarized() && matches!(scene.integrator, Integrator::VolPath(_)) {
        anyhow::bail!("{what}: volpath renders in the rgb and spectral modes only; its media do not carry polarization (use --mode rgb or spectral)");
    }
    if mode.polarized() {
        if let Some(b) = scene.bsdfs.iter().find(|b| !b.has_mueller_model()) {
            anyhow::bail!(
                "{what}: the polarized modes support diffuse, dielectric, thindielectric, conductor, plastic, polarizer, retarder, roughconductor, roughdielectric, roughplastic, pplastic and birefringent BSDFs (and twosided of them); this scene has a \"{}\" BSDF (render it with --mode rgb or spectral)",
                b.plugin()
            );
        }
    }
    if mode.spectral() {
        crate::spectrum::uplift::RgbUplift::get();
    }
    Ok(())
}

/// Renders `scene` in `mode` (after [`prepare`]), in the passes that
/// `options` asks for, calling `on_pass` after each.
pub fn render(
    scene: &Scene,
    mode: Mode,
    options: &RenderOptions,
    on_pass: &mut dyn FnMut(&PassReport),
) -> anyhow::Result<(Image, RenderStats)> {
    match mode {
        Mode::Rgb => render_passes::<Rgb>(scene, options, on_pass),
        Mode::Spectral => render_passes::<Sampled>(scene, options, on_pass),
        Mode::RgbPolarized => render_passes::<Polarized<Rgb>>(scene, options, on_pass),
        Mode::SpectralPolarized => render_passes::<Polarized<Sampled>>(scene, options, on_pass),
    }
}

/// [`render`], continuing from `resume` (a saved [`FilmState`] of this scene
/// and mode holding samples `[0, k)`) if given, and returning the final
/// state too (to save as a checkpoint, or merge).
pub fn render_from(
    scene: &Scene,
    mode: Mode,
    options: &RenderOptions,
    resume: Option<FilmState>,
    on_pass: &mut dyn FnMut(&PassReport),
) -> anyhow::Result<(Image, RenderStats, FilmState)> {
    match mode {
        Mode::Rgb => render_progressive::<Rgb>(scene, options, resume, on_pass),
        Mode::Spectral => render_progressive::<Sampled>(scene, options, resume, on_pass),
        Mode::RgbPolarized => render_progressive::<Polarized<Rgb>>(scene, options, resume, on_pass),
        Mode::SpectralPolarized => render_progressive::<Polarized<Sampled>>(scene, options, resume, on_pass),
    }
}

/// Renders samples `samples` of every pixel of `scene` in `mode` (after
/// [`prepare`]): the exact state that [`FilmState::merge`] adds to the
/// states of other ranges (rendered elsewhere) and [`FilmState::develop`]
/// turns into the image. See [`crate::render::render_samples`].
pub fn render_samples(scene: &Scene, mode: Mode, options: &RenderOptions, samples: std::ops::Range<u32>) -> anyhow::Result<FilmState> {
    match mode {
        Mode::Rgb => crate::render::render_samples::<Rgb>(scene, options, samples),
        Mode::Spectral => crate::render::render_samples::<Sampled>(scene, options, samples),
        Mode::RgbPolarized => crate::render::render_samples::<Polarized<Rgb>>(scene, options, samples),
        Mode::SpectralPolarized => crate::render::render_samples::<Polarized<Sampled>>(scene, options, samples),
    }
}

/// [`render_samples`] for the pixels of one tile (x, y, width, height in
/// crop-window coordinates): see [`crate::render::render_tile_samples`].
pub fn render_tile_samples(scene: &Scene, mode: Mode, options: &RenderOptions, samples: std::ops::Range<u32>, tile: [u32; 4]) -> anyhow::Result<FilmState> {
    match mode {
        Mode::Rgb => crate::render::render_tile_samples::<Rgb>(scene, options, samples, tile),
        Mode::Spectral => crate::render::render_tile_samples::<Sampled>(scene, options, samples, tile),
        Mode::RgbPolarized => crate::render::render_tile_samples::<Polarized<Rgb>>(scene, options, samples, tile),
        Mode::SpectralPolarized => crate::render::render_tile_samples::<Polarized<Sampled>>(scene, options, samples, tile),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_names_round_trip_and_unknown_lists_choices() {
        for m in Mode::ALL {
            assert_eq!(Mode::from_name(m.name()).unwrap(), m);
        }
        assert_eq!(Mode::from_name("Spectral_Polarized").unwrap(), Mode::SpectralPolarized);
        let e = Mode::from_name("hyperspectral").unwrap_err().to_string();
        assert!(e.contains("hyperspectral") && e.contains("rgb-polarized"), "{e}");
    }
}
