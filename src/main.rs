//! The `snell` command-line tool.

use anyhow::Context;
use clap::{Args, Parser, Subcommand, ValueEnum};
use snell::film::output::{Format, write_image};
use snell::spectrum::{Polarized, Rgb, Sampled};
use snell::{LoadOptions, RenderOptions};
use std::collections::HashMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

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
    /// Set a scene parameter declared with <default name=…>, as NAME=VALUE. Repeatable.
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    define: Vec<String>,
    /// Worker threads (default: all cores).
    #[arg(short, long, default_value_t = 0)]
    threads: usize,
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
    /// *_polarized variants; so far for scenes of diffuse surfaces, smooth
    /// dielectrics and conductors, and polarizers, and the image is S0).
    #[arg(long, value_enum, default_value_t = Mode::Rgb)]
    mode: Mode,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Mode {
    Rgb,
    Spectral,
    RgbPolarized,
    SpectralPolarized,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let args = match cli.command {
        Some(Command::Render(args)) => args,
        None => match default_render() {
            Ok(args) => args,
            Err(e) => {
                eprintln!("error: {e:#}");
                return ExitCode::FAILURE;
            }
        },
    };
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            match e.downcast_ref::<snell::SceneError>() {
                Some(se) => eprintln!("{se}"),
                None => eprintln!("error: {e:#}"),
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
        define: vec![],
        threads: 0,
        seed: None,
        stats: None,
        quiet: false,
        mode: Mode::Rgb,
    })
}

fn run(args: RenderArgs) -> anyhow::Result<()> {
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
    let outputs = if args.output.is_empty() {
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

    let load_start = std::time::Instant::now();
    let options = LoadOptions { params, spp: args.spp, seed: args.seed };
    let scene = snell::load_file(&args.scene, &options)?;
    if matches!(args.mode, Mode::RgbPolarized | Mode::SpectralPolarized) {
        if let Some(b) = scene.bsdfs.iter().find(|b| !b.has_mueller_model()) {
            anyhow::bail!(
                "{}: the polarized modes support diffuse, dielectric, conductor, polarizer and retarder BSDFs so far; this scene has a \"{}\" BSDF (render it with --mode rgb or spectral)",
                args.scene.display(),
                b.plugin()
            );
        }
    }
    if matches!(args.mode, Mode::Spectral | Mode::SpectralPolarized) {
        // Fit the RGB uplift table now, so rendering time excludes it.
        snell::spectrum::uplift::RgbUplift::get();
    }
    let load_seconds = load_start.elapsed().as_secs_f64();

    let show = !args.quiet && std::io::stderr().is_terminal();
    let render_options = RenderOptions { threads: args.threads, progress: show };
    let (image, stats) = match args.mode {
        Mode::Rgb => snell::render::<Rgb>(&scene, &render_options)?,
        Mode::Spectral => snell::render::<Sampled>(&scene, &render_options)?,
        Mode::RgbPolarized => snell::render::<Polarized<Rgb>>(&scene, &render_options)?,
        Mode::SpectralPolarized => snell::render::<Polarized<Sampled>>(&scene, &render_options)?,
    };
    for o in &outputs {
        write_image(&image, o)?;
    }
    if let Some(path) = &args.stats {
        let mut json = serde_json::to_value(&stats)?;
        json["load_seconds"] = load_seconds.into();
        json["scene"] = args.scene.display().to_string().into();
        json["mode"] = args.mode.to_possible_value().map_or_else(String::new, |v| v.get_name().to_string()).into();
        std::fs::write(path, serde_json::to_string_pretty(&json)? + "\n").with_context(|| format!("cannot write {}", path.display()))?;
    }
    if !args.quiet {
        let names: Vec<String> = outputs.iter().map(|o| o.display().to_string()).collect();
        eprintln!(
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
        if stats.invalid_samples > 0 {
            eprintln!("warning: {} samples were NaN or infinite and were set to zero", stats.invalid_samples);
        }
    }
    Ok(())
}
