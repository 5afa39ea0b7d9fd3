//! The `snell` command line: `snell render SCENE …`. It lives in the library
//! so that the `snell` binary and the Python package's `snell` command run
//! the same code ([`main_with_args`]).

use anyhow::Context;
use clap::{Args, Parser, Subcommand, ValueEnum};
use crate::film::output::{ExrMetadata, Format, write_image, write_image_with};
use crate::{LoadOptions, RenderOptions};
use std::collections::HashMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// `eprintln!` that ignores a closed or failing stderr instead of panicking
/// (`snell render … 2>&1 | head -c0`).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// The most worker threads `--threads` accepts.
const MAX_THREADS: usize = 4096;

#[derive(Parser)]
#[command(name = "snell", version, about = "A physically based renderer for Mitsuba 3 XML scenes")]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an image.
    Render(RenderArgs),
}

#[derive(Args)]
struct RenderArgs {
    /// The Mitsuba 3 XML scene file.
    scene: PathBuf,
    /// Output image(s): .exr (linear float), .png (8-bit sRGB) or .pfm. Repeatable.
    /// Default: the scene's name with .exr, in the current folder.
    #[arg(short, long = "output")]
    output: Vec<PathBuf>,
    /// Samples per pixel (overrides the scene's sampler).
    #[arg(long)]
    spp: Option<u32>,
    /// Render the film this many pixels wide, its height scaled to keep the
    /// aspect ratio (any crop window reset): quick previews of any scene.
    #[arg(long, value_name = "PIXELS")]
    width: Option<u32>,
    /// Set a scene parameter declared with <default name=…>, as NAME=VALUE. Repeatable.
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    define: Vec<String>,
    /// Worker threads (default: all cores; at most 4096).
    #[arg(short, long, default_value_t = 0)]
    threads: usize,
    /// Largest texture image accepted, in pixels (e.g. 16384*16384); checked
    /// from the image's header before it is decoded. Default 2^28, or the
    /// environment variable SNELL_MAX_IMAGE_PIXELS.
    #[arg(long, value_name = "PIXELS")]
    max_image_pixels: Option<String>,
    /// Memory budget of the film while rendering, in MB (estimated before
    /// anything is allocated). Default 8192, or SNELL_MAX_FILM_BYTES (bytes).
    #[arg(long, value_name = "MB")]
    max_film_mb: Option<u64>,
    /// Sampler seed (overrides the scene's).
    #[arg(long)]
    seed: Option<u64>,
    /// Write render statistics (size, spp, threads, timing) as JSON to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// No progress bar and no summary line.
    #[arg(short, long)]
    quiet: bool,
    /// What a light path carries: RGB triples (as Mitsuba's *_rgb variants),
    /// four sampled wavelengths (as its *_spectral variants; needed for
    /// dispersion), or either with a Mueller matrix per channel (as its
    /// *_polarized variants). Polarized renders write the Stokes components
    /// S0–S3 as extra EXR channels (S1.R, …, S3.B), measured in the camera's
    /// frame with S1 > 0 for horizontal polarization.
    #[arg(long, value_enum, default_value_t = Mode::Rgb)]
    mode: Mode,
    /// Also write a false-colour PNG of the linear polarization (hue: angle,
    /// brightness: degree) to this file. Needs a polarized --mode.
    #[arg(long, value_name = "FILE.png")]
    stokes_view: Option<PathBuf>,
    /// Watch the render in the browser: serve a live preview on this port
    /// (default 8730; 0 picks a free one) and print its URL. The image is
    /// rendered in passes (1, 2, 4, … spp) and shown after each; the page's
    /// Stop button ends the render as Ctrl-C does. Put it after the scene.
    #[arg(long, value_name = "PORT", num_args = 0..=1, default_missing_value = "8730")]
    preview: Option<u16>,
    /// The address the preview listens on (default 127.0.0.1: this machine
    /// only; 0.0.0.0 lets other machines watch).
    #[arg(long, value_name = "ADDR", requires = "preview")]
    preview_bind: Option<std::net::IpAddr>,
    /// Testing aid: with --preview, also write each pass's image as
    /// DIR/pass-001.exr, pass-002.exr, … (the image the page is sent).
    #[arg(long, value_name = "DIR", requires = "preview")]
    preview_dump_passes: Option<PathBuf>,
    /// Render in this many passes of doubling sample counts (each pass adds
    /// new samples to the previous ones; the image is the same, bit for bit,
    /// for any number of passes). Default: 5 (the first pass has 1/16 of the
    /// samples), fewer when there are fewer samples per pixel.
    #[arg(long, value_name = "N")]
    passes: Option<u32>,
    /// After a pass, write the outputs (a checkpoint: the .exr holds the
    /// exact state to --resume from) if this many seconds have passed since
    /// the last write; 0 writes after every pass.
    #[arg(long, value_name = "SECONDS")]
    write_every: Option<f64>,
    /// Continue the render saved in this .exr (by --write-every or an
    /// interruption) with the same scene and options; the result is the
    /// image of an uninterrupted render, bit for bit. Writes to it unless -o
    /// is given.
    #[arg(long, value_name = "OUT.exr")]
    resume: Option<PathBuf>,
    /// Adaptive sampling: a pixel stops taking samples once its estimated
    /// relative standard error (over √(value² + 0.01), so below 0.1 the
    /// absolute error; from its own samples and its 3 × 3 neighbours') is
    /// below this, e.g. 0.02; --spp is then the most a pixel gets. Renders
    /// in rounds (--min-spp for every pixel, then doubling for the pixels
    /// still noisy); the EXR gets a channel `spp`, each pixel's samples.
    /// Camera-path integrators only; not with --passes, --write-every or
    /// --resume.
    #[arg(long, value_name = "T")]
    noise_threshold: Option<f64>,
    /// With --noise-threshold: the samples every pixel gets before the
    /// first decision (default: --spp / 8, at least 16).
    #[arg(long, value_name = "N", requires = "noise_threshold")]
    min_spp: Option<u32>,
}

impl RenderArgs {
    fn threshold_invalid(&self) -> bool {
        self.noise_threshold.is_some_and(|t| !(t.is_finite() && t > 0.0))
    }
}

/// Passes of a command-line render unless --passes says otherwise: the
/// first pass holds 1/16 of the samples, so an interruption after it still
/// writes an image with every pixel rendered. Each pass costs a film state,
/// a merge and a developed image, so the passes after the first are joined
/// into one when they are due to end within two seconds
/// ([`RenderOptions::join_passes_under`]).
const DEFAULT_PASSES: u32 = 5;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Mode {
    Rgb,
    Spectral,
    RgbPolarized,
    SpectralPolarized,
}

impl From<Mode> for crate::Mode {
    fn from(m: Mode) -> crate::Mode {
        match m {
            Mode::Rgb => crate::Mode::Rgb,
            Mode::Spectral => crate::Mode::Spectral,
            Mode::RgbPolarized => crate::Mode::RgbPolarized,
            Mode::SpectralPolarized => crate::Mode::SpectralPolarized,
        }
    }
}

/// Runs the command line on `args` (the program name first, as
/// `std::env::args_os()` gives them) and returns the process's exit code.
/// `--help`, `--version` and usage errors print and exit as clap does.
pub fn main_with_args<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = Cli::parse_from(args);
    let args = match cli.command {
        Some(Command::Render(args)) => args,
        None => match default_render() {
            Ok(args) => args,
            Err(e) => {
                say!("error: {e:#}");
                return ExitCode::FAILURE;
            }
        },
    };
    match run(args) {
        Ok(code) => code,
        Err(e) => {
            match e.downcast_ref::<crate::SceneError>() {
                Some(se) => say!("{se}"),
                None => say!("error: {e:#}"),
            }
            ExitCode::FAILURE
        }
    }
}

/// `snell` with no arguments renders the bundled Cornell box to
/// cornell-box.exr and cornell-box.png.
fn default_render() -> anyhow::Result<RenderArgs> {
    let rel = Path::new("scenes/cornell-box.xml");
    let scene = if rel.exists() { rel.to_path_buf() } else { Path::new(env!("CARGO_MANIFEST_DIR")).join(rel) };
    if !scene.exists() {
        anyhow::bail!("no scene given and the bundled {} is missing; try `snell render SCENE`", rel.display());
    }
    Ok(RenderArgs {
        scene,
        output: vec!["cornell-box.exr".into(), "cornell-box.png".into()],
        spp: None,
        width: None,
        define: vec![],
        threads: 0,
        max_image_pixels: None,
        max_film_mb: None,
        seed: None,
        stats: None,
        quiet: false,
        mode: Mode::Rgb,
        stokes_view: None,
        preview: None,
        preview_bind: None,
        preview_dump_passes: None,
        passes: None,
        write_every: None,
        resume: None,
        noise_threshold: None,
        min_spp: None,
    })
}

/// Checks every output before the render: a known format, an existing and
/// writable folder, and no file named twice.
fn check_outputs(images: &[&PathBuf], stats: Option<&PathBuf>) -> anyhow::Result<()> {
    let mut seen: Vec<PathBuf> = vec![];
    for p in images.iter().copied().chain(stats) {
        let abs = std::path::absolute(p).unwrap_or_else(|_| p.clone());
        if seen.contains(&abs) {
            anyhow::bail!("{} is given twice as an output; name each output once", p.display());
        }
        seen.push(abs);
    }
    for p in images {
        crate::film::output::check_writable(p)?;
    }
    if let Some(p) = stats {
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if !dir.is_dir() {
            anyhow::bail!("cannot write the statistics {}: its folder {} does not exist", p.display(), dir.display());
        }
    }
    Ok(())
}

fn run(args: RenderArgs) -> anyhow::Result<ExitCode> {
    let mut params = HashMap::new();
    for d in &args.define {
        let (k, v) = d.split_once('=').with_context(|| format!("-D {d}: expected NAME=VALUE"))?;
        if k.is_empty() || !k.chars().all(|c| c.is_alphanumeric() || c == '_') {
            anyhow::bail!("-D {d}: \"{k}\" is not a valid parameter name");
        }
        params.insert(k.to_string(), v.to_string());
    }
    if args.spp == Some(0) {
        anyhow::bail!("--spp must be at least 1");
    }
    if let Some(spp) = args.spp.filter(|&n| n > crate::scene::loader::MAX_SPP) {
        anyhow::bail!("--spp {spp} is above the limit of {} (2^24), the same as a scene's sample_count", crate::scene::loader::MAX_SPP);
    }
    let outputs = if let (true, Some(resume)) = (args.output.is_empty(), &args.resume) {
        vec![resume.clone()]
    } else if args.output.is_empty() {
        let stem = args.scene.file_stem().map_or("render".into(), |s| s.to_string_lossy().to_string());
        vec![PathBuf::from(format!("{stem}.exr"))]
    } else {
        args.output.clone()
    };
    for o in &outputs {
        if Format::from_path(o).is_none() {
            anyhow::bail!("cannot tell the image format of {}: use one of .{}", o.display(), Format::EXTENSIONS.join(", ."));
        }
    }
    if args.threads > MAX_THREADS {
        anyhow::bail!("--threads {} is more than the {MAX_THREADS} worker threads Snell starts at most", args.threads);
    }
    if let Some(s) = &args.max_image_pixels {
        let n = crate::limits::parse_count(s)
            .with_context(|| format!("--max-image-pixels {s}: expected a pixel count such as 100000000 or 16384*16384"))?;
        crate::limits::set_max_image_pixels(n);
    }
    if let Some(mb) = args.max_film_mb {
        crate::limits::set_max_film_bytes(mb.saturating_mul(1 << 20));
    }
    let polarized = matches!(args.mode, Mode::RgbPolarized | Mode::SpectralPolarized);
    if let Some(view) = &args.stokes_view {
        if !polarized {
            anyhow::bail!("--stokes-view needs a polarized mode: add --mode rgb-polarized or --mode spectral-polarized");
        }
        if Format::from_path(view) != Some(Format::Png) {
            anyhow::bail!("--stokes-view {}: the polarization view is written as .png", view.display());
        }
    }

    if args.passes == Some(0) {
        anyhow::bail!("--passes must be at least 1");
    }
    let adaptive = args.noise_threshold.map(|threshold| crate::render::Adaptive { threshold, min_spp: args.min_spp.unwrap_or(0) });
    if adaptive.is_some() {
        // Its rounds are its passes; its pixels end with different sample
        // counts, which a checkpoint's film state does not record.
        if args.passes.is_some() {
            anyhow::bail!("--noise-threshold renders in its own rounds (--min-spp, then doubling): leave out --passes");
        }
        if args.write_every.is_some() || args.resume.is_some() {
            anyhow::bail!(
                "--noise-threshold cannot be combined with --write-every or --resume: an adaptive render's pixels hold different sample counts, which a checkpoint does not record"
            );
        }
        if args.threshold_invalid() {
            anyhow::bail!("--noise-threshold {}: expected a positive relative error such as 0.02", args.noise_threshold.unwrap_or(0.0));
        }
        if args.min_spp == Some(0) {
            anyhow::bail!("--min-spp must be at least 1");
        }
    }
    if let Some(s) = args.write_every.filter(|s| !(s.is_finite() && *s >= 0.0)) {
        anyhow::bail!("--write-every {s}: expected a number of seconds, 0 or more");
    }
    let checkpoints = args.write_every.is_some() || args.resume.is_some();
    if checkpoints && !outputs.iter().any(|o| Format::from_path(o) == Some(Format::Exr)) {
        anyhow::bail!("--write-every and --resume need an .exr output, which holds the state to resume from");
    }
    let images: Vec<&PathBuf> = outputs.iter().chain(&args.stokes_view).collect();
    check_outputs(&images, args.stats.as_ref())?;

    let load_start = std::time::Instant::now();
    let options = LoadOptions { params, spp: args.spp, seed: args.seed };
    let scene = match args.width {
        Some(0) => anyhow::bail!("--width must be at least 1"),
        Some(w) => crate::scene::loader::load_file_at_width(&args.scene, &options, w)?,
        None => crate::load_file(&args.scene, &options)?,
    };
    if !args.quiet {
        for w in &scene.warnings {
            say!("{w}");
        }
    }
    if let crate::integrator::Integrator::Path(pt) = &scene.integrator {
        if pt.reuse_pixels > 1 && !args.quiet && !crate::integrator::path_reuse::applies_to(&scene, pt, args.mode == Mode::Rgb) {
            say!("warning: reuse_pixels applies to path in the rgb mode without splitting, guiding, pass-through shapes or rr_depth 1; rendering without it");
        }
    }
    if scene.stokes_requested && !polarized && !args.quiet {
        say!("warning: the scene's stokes integrator writes S1–S3 only in a polarized mode (--mode rgb-polarized or spectral-polarized); writing the intensity image");
    }
    crate::session::prepare(&scene, args.mode.into(), &args.scene.display().to_string())?;
    let load_seconds = load_start.elapsed().as_secs_f64();

    let show = !args.quiet && std::io::stderr().is_terminal();
    // Ctrl-C or SIGTERM: finish the work under way, write what was rendered,
    // exit 130. A second signal exits at once.
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let handler = ctrlc::set_handler(move || {
        if flag.swap(true, Ordering::SeqCst) {
            std::process::exit(130);
        }
    });
    if let Err(e) = handler {
        if !args.quiet {
            say!("warning: cannot install the Ctrl-C handler ({e}); an interrupted render will not be saved");
        }
    }
    let preview = match args.preview {
        Some(port) => {
            let bind = args.preview_bind.unwrap_or(std::net::Ipv4Addr::LOCALHOST.into());
            let [_, _, w, h] = scene.film.crop;
            let p = crate::preview::Preview::start((bind, port).into(), args.mode.into(), w, h, stop.clone())?;
            say!("preview: {}", p.url());
            Some(p)
        }
        None => None,
    };
    if let Some(dir) = &args.preview_dump_passes {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create the folder {}", dir.display()))?;
    }
    let checkpoint = Checkpoint::new(&args, &scene);
    let resume = match &args.resume {
        Some(path) => match checkpoint.read(path)? {
            Some(state) => Some(state),
            None => {
                if !args.quiet {
                    say!("{} already holds all {} samples per pixel of this render; nothing to do", path.display(), scene.sampler.sample_count);
                }
                return Ok(ExitCode::SUCCESS);
            }
        },
        None => None,
    };
    let passes = if adaptive.is_some() {
        1
    } else {
        args.passes.unwrap_or(if preview.is_some() { crate::preview::default_passes(scene.sampler.sample_count) } else { DEFAULT_PASSES })
    };
    if let Some(a) = &adaptive {
        // The option errors (min above spp) before the render starts.
        a.min_spp_of(scene.sampler.sample_count).map_err(|e| anyhow::anyhow!("--noise-threshold: {e}"))?;
    }
    // Without --passes or a preview, the passes are only a safety net for
    // interruptions: the rest of a render due to end within two seconds is
    // rendered as one pass.
    let join_passes_under = (args.passes.is_none() && preview.is_none()).then_some(2.0);
    let render_options =
        RenderOptions { threads: args.threads, progress: show, stop: Some(stop.clone()), passes, adaptive, join_passes_under, ..RenderOptions::default() };
    let write_all = |image: &crate::film::Image, state: Option<&crate::film::FilmState>| -> anyhow::Result<()> {
        let meta = if adaptive.is_some() { checkpoint.adaptive_metadata() } else { checkpoint.metadata(state) };
        for o in &outputs {
            write_image_with(image, o, &meta)?;
        }
        if let Some(view) = &args.stokes_view {
            let picture = crate::film::stokes::stokes_view(image).context("the render has no Stokes layers")?;
            write_image(&picture, view)?;
        }
        Ok(())
    };
    let mut last_write = std::time::Instant::now();
    let mut write_error = None;
    let mut on_pass = |report: &crate::PassReport| {
        // The file first: a page that shows a pass finds its EXR written.
        if let Some(dir) = &args.preview_dump_passes {
            let path = dir.join(format!("pass-{:03}.exr", report.pass));
            if let Err(e) = write_image(report.image, &path) {
                say!("warning: {e:#}");
            }
        }
        if let Some(p) = &preview {
            p.publish(report);
        }
        if adaptive.is_some() && !args.quiet {
            let pixels = report.image.width as f64 * report.image.height as f64;
            let taken = report.state.header.samples_taken;
            say!(
                "adaptive round {}/{}: {:.1}% of the pixels to {} spp; {} samples in all (mean {:.1} spp), {:.2} s",
                report.pass,
                report.passes,
                100.0 * report.active_fraction,
                report.spp_done,
                taken,
                taken as f64 / pixels.max(1.0),
                report.elapsed_seconds
            );
        }
        let Some(every) = args.write_every else { return };
        if report.spp_done < report.spp_total && write_error.is_none() && last_write.elapsed().as_secs_f64() >= every {
            if let Err(e) = write_all(report.image, Some(report.state)) {
                // Stop: a render that cannot save its checkpoints should not go on for hours.
                write_error = Some(e);
                stop.store(true, Ordering::SeqCst);
            }
            last_write = std::time::Instant::now();
        }
    };
    let (image, stats, state) = crate::session::render_from(&scene, args.mode.into(), &render_options, resume, &mut on_pass)?;
    if let Some(e) = write_error {
        return Err(e.context("writing a checkpoint"));
    }
    // An interrupted render keeps its state (when it has a complete pass) so
    // that --resume can continue it.
    write_all(&image, Some(&state))?;
    if let Some(path) = &args.stats {
        let mut json = serde_json::to_value(&stats)?;
        json["load_seconds"] = load_seconds.into();
        json["scene"] = args.scene.display().to_string().into();
        json["simd"] = scene.accel.simd_level().name().into();
        json["bvh_nodes"] = if scene.accel.quantized() { "quantized" } else { "full" }.into();
        json["bvh_node_bytes"] = scene.accel.node_bytes().into();
        json["bvh_bytes"] = scene.accel.memory_bytes().into();
        json["mode"] = args.mode.to_possible_value().map_or_else(String::new, |v| v.get_name().to_string()).into();
        std::fs::write(path, serde_json::to_string_pretty(&json)? + "\n").with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(p) = &preview {
        p.finish(&stats);
    }
    if let (true, Some(a)) = (stats.interrupted, &stats.adaptive) {
        let names: Vec<String> = outputs.iter().chain(&args.stokes_view).map(|o| o.display().to_string()).collect();
        say!(
            "interrupted: wrote the adaptive render's last complete round (mean {:.1} spp, {} to {} per pixel) → {} (an adaptive render cannot be resumed)",
            a.mean_spp,
            a.least_spp,
            a.most_spp,
            names.join(", ")
        );
        return Ok(ExitCode::from(130));
    }
    if stats.interrupted && stats.spp_done > 0 {
        let names: Vec<String> = outputs.iter().chain(&args.stokes_view).map(|o| o.display().to_string()).collect();
        say!(
            "interrupted: wrote the last complete pass ({} of {} spp, every pixel) → {}; continue it with --resume {}",
            stats.spp_done,
            stats.spp,
            names.join(", "),
            outputs.iter().find(|o| Format::from_path(o) == Some(Format::Exr)).map_or(String::new(), |o| o.display().to_string())
        );
        return Ok(ExitCode::from(130));
    }
    if stats.interrupted {
        let names: Vec<String> = outputs.iter().chain(&args.stokes_view).map(|o| o.display().to_string()).collect();
        say!(
            "interrupted: wrote the partial image ({} of {} samples, {:.1}%; each rendered pixel has {} spp, the rest are black) → {}",
            stats.samples_taken,
            stats.samples_planned,
            100.0 * stats.samples_taken as f64 / stats.samples_planned.max(1) as f64,
            stats.spp,
            names.join(", ")
        );
        return Ok(ExitCode::from(130));
    }
    if !args.quiet {
        let names: Vec<String> = outputs.iter().chain(&args.stokes_view).map(|o| o.display().to_string()).collect();
        say!(
            "rendered {}×{} at {} spp in {:.2} s ({:.2} M samples/s, {} threads; loading {:.2} s) → {}",
            stats.width,
            stats.height,
            stats.spp,
            stats.render_seconds,
            stats.samples_per_second / 1e6,
            stats.threads,
            load_seconds,
            names.join(", ")
        );
        if let Some(a) = &stats.adaptive {
            say!(
                "adaptive: {:.1} spp on average ({} to {} per pixel; threshold {}), {} samples",
                a.mean_spp,
                a.least_spp,
                a.most_spp,
                a.threshold,
                stats.samples_taken
            );
        }
        if stats.invalid_samples > 0 {
            say!("warning: {} samples were NaN or infinite and were set to zero", stats.invalid_samples);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// The EXR header attribute saying which render an output is of and which
/// samples it holds: `samples=0-64; scene=…; mode=rgb; size=…; spp=64; seed=0`
/// (`samples=partial` for an interrupted first pass).
pub const RENDER_ATTRIBUTE: &str = "snell.render";

/// The `name=value` fields of a [`RENDER_ATTRIBUTE`].
pub fn parse_fields(text: &str) -> Vec<(String, String)> {
    text.split(';').filter_map(|f| f.split_once('=')).map(|(k, v)| (k.trim().to_string(), v.trim().to_string())).collect()
}

/// What a checkpoint's EXR header says about the render it holds, to check
/// that `--resume` continues the same render. Public so that a distributed
/// render (the Python package's `snell.distributed`) writes and reads the
/// same checkpoints as the command line.
pub struct Checkpoint {
    /// name, value: the checked attributes, each compared on resume.
    identity: Vec<(&'static str, String)>,
    /// The scene's other files ([`crate::Scene::files`]): name (relative to
    /// the scene's folder where it lies below it) and content digest, kept
    /// in the [`FILES_ATTRIBUTE`] to name the file that changed.
    files: Vec<(String, String)>,
    sample_count: u32,
}

/// The header attribute that lists a checkpoint's input files, one
/// `DIGEST NAME` line each (see [`file_digest`]).
pub const FILES_ATTRIBUTE: &str = "snell.files";

/// A file's content digest: its size in bytes and the CRC-32 of its bytes,
/// `SIZE-CRC` (hex). Hashing the content (not the modification time) lets a
/// checkpoint resume on another machine or after a copy; CRC-32 runs at
/// several GB/s, a small cost beside parsing the file.
fn file_digest(path: &Path) -> String {
    use std::io::Read;
    let Ok(mut file) = std::fs::File::open(path) else { return "unreadable".to_string() };
    let (mut hasher, mut size, mut buf) = (crc32fast::Hasher::new(), 0u64, vec![0u8; 1 << 20]);
    loop {
        match file.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                hasher.update(&buf[..n]);
                size += n as u64;
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(_) => return "unreadable".to_string(),
        }
    }
    format!("{size:x}-{:08x}", hasher.finalize())
}

impl Checkpoint {
    fn new(args: &RenderArgs, scene: &crate::Scene) -> Checkpoint {
        let text = std::fs::read(&args.scene).unwrap_or_default();
        Checkpoint::of(&text, &args.define, scene, args.mode.into())
    }

    /// The checkpoints of a render of `scene` (loaded from a file holding
    /// `text`, with the `-D` definitions `defines`, each `NAME=VALUE`) in
    /// `mode`.
    pub fn of(text: &[u8], defines: &[String], scene: &crate::Scene, mode: crate::Mode) -> Checkpoint {
        // The scene file's bytes, the -D definitions and the digests of the
        // files it reads (included XML, meshes, images), named relative to
        // the scene's folder.
        let mut defines = defines.to_vec();
        defines.sort();
        let files: Vec<(String, String)> = scene
            .files
            .iter()
            .map(|f| (f.strip_prefix(&scene.folder).unwrap_or(f).display().to_string().replace('\n', " "), file_digest(f)))
            .collect();
        let listed: String = files.iter().map(|(name, digest)| format!("\n{digest} {name}")).collect();
        let digest = text
            .iter()
            .chain(defines.join("\n").as_bytes())
            .chain(listed.as_bytes())
            .fold(0xcbf2_9ce4_8422_2325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3));
        let [ox, oy, w, h] = scene.film.crop;
        Checkpoint {
            identity: vec![
                ("scene", format!("{:016x}", crate::math::rng::mix64(digest))),
                ("mode", mode.name().to_string()),
                ("size", format!("{}x{} crop {w}x{h}+{ox}+{oy}", scene.film.width, scene.film.height)),
                ("spp", scene.sampler.sample_count.to_string()),
                ("seed", scene.sampler.seed.to_string()),
            ],
            files,
            sample_count: scene.sampler.sample_count,
        }
    }

    /// The header attributes of an output holding `state`: which samples it
    /// holds, and the exact state itself when the render can be resumed (a
    /// complete pass, not the last).
    pub fn metadata(&self, state: Option<&crate::film::FilmState>) -> ExrMetadata {
        let mut meta = ExrMetadata::default();
        let samples = match state {
            Some(s) if s.header.complete => s.ranges().iter().map(|r| format!("{}-{}", r.start, r.end)).collect::<Vec<_>>().join(","),
            _ => "partial".to_string(),
        };
        // One attribute (EXR writers order attributes as they like; one
        // keeps the file a function of the image).
        let fields: Vec<String> = std::iter::once(format!("samples={samples}")).chain(self.identity.iter().map(|(k, v)| format!("{k}={v}"))).collect();
        meta.text.push((RENDER_ATTRIBUTE.into(), fields.join("; ")));
        if !self.files.is_empty() {
            let lines: Vec<String> = self.files.iter().map(|(name, digest)| format!("{digest} {name}")).collect();
            meta.text.push((FILES_ATTRIBUTE.into(), lines.join("\n")));
        }
        if let Some(s) = state.filter(|s| s.header.complete && !s.is_finished()) {
            meta.state = Some(s.to_bytes());
        }
        meta
    }

    /// The header attributes of the output of an adaptive render: the same,
    /// with `samples=adaptive` (its pixels hold different sample counts)
    /// and no state, so that --resume refuses it.
    pub fn adaptive_metadata(&self) -> ExrMetadata {
        let mut meta = self.metadata(None);
        for (name, value) in &mut meta.text {
            if name == RENDER_ATTRIBUTE {
                *value = value.replacen("samples=partial", "samples=adaptive", 1);
            }
        }
        meta
    }

    /// The state to continue from in the checkpoint `path`, or `None` if it
    /// already holds the whole render; an error if it is of another render
    /// or holds no state.
    pub fn read(&self, path: &Path) -> anyhow::Result<Option<crate::film::FilmState>> {
        let meta = crate::film::output::read_exr_metadata(path).with_context(|| format!("--resume {}", path.display()))?;
        let fields = meta.text.iter().find(|(n, _)| n == RENDER_ATTRIBUTE).map(|(_, v)| parse_fields(v)).unwrap_or_default();
        let get = |k: &str| fields.iter().find(|(n, _)| n == k).map(|(_, v)| v.as_str());
        if get("samples").is_none() {
            anyhow::bail!("--resume {}: not a Snell checkpoint (its header has no {RENDER_ATTRIBUTE} attribute)", path.display());
        }
        // A changed input file, named (its digest is also in the scene's).
        let saved_files: Vec<(&str, &str)> = meta
            .text
            .iter()
            .find(|(n, _)| n == FILES_ATTRIBUTE)
            .map(|(_, v)| v.lines().filter_map(|l| l.split_once(' ')).map(|(d, n)| (n, d)).collect())
            .unwrap_or_default();
        for (name, digest) in &self.files {
            match saved_files.iter().find(|(n, _)| n == name) {
                Some((_, d)) if d == digest => {}
                Some((_, d)) => anyhow::bail!(
                    "--resume {}: the scene's file {name} has changed since the checkpoint was written (size-CRC32 {d}, now {digest}); restore it or render again without --resume",
                    path.display()
                ),
                None if meta.text.iter().any(|(n, _)| n == FILES_ATTRIBUTE) => anyhow::bail!(
                    "--resume {}: the scene now reads the file {name}, which the checkpoint's render did not; render again without --resume",
                    path.display()
                ),
                None => {}
            }
        }
        for (name, value) in &self.identity {
            let saved = get(name).unwrap_or("none");
            if saved != value {
                let what = name;
                anyhow::bail!(
                    "--resume {}: the checkpoint is of another render ({what} {saved}, this render's {what} is {value}); resume with the same scene, -D, --width, --spp, --seed and --mode",
                    path.display()
                );
            }
        }
        if get("samples") == Some(&format!("0-{}", self.sample_count)) {
            return Ok(None);
        }
        let bytes = meta.state.ok_or_else(|| {
            anyhow::anyhow!("--resume {}: holds no resumable state (samples {}); render it again without --resume", path.display(), get("samples").unwrap_or("?"))
        })?;
        let state = crate::film::FilmState::from_bytes(&bytes).with_context(|| format!("--resume {}", path.display()))?;
        Ok(Some(state))
    }
}
