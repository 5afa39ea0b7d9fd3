//! `snell._snell`: the native half of the Python package `snell`.
//!
//! The Python half (`snell/__init__.py`) holds the public API, its
//! docstrings and the dictionary → XML conversion; this module holds what
//! needs Rust: loading, rendering with the GIL released (and Ctrl-C turned
//! into the render's stop flag), image conversion to and from flat float32
//! buffers, and the command line. Every entry point runs under
//! `catch_unwind`, so a bug in Snell raises `RuntimeError` instead of
//! aborting the interpreter.
//!
//! Library calls: `snell::load_file`, `snell::load_str` (with
//! `LoadOptions { params, spp, seed }`), `snell::session::{prepare, render}`
//! (with `RenderOptions { threads, stop, passes, .. }` and the `PassReport`
//! callback), `snell::film::output::{write_image, read_exr}`,
//! `snell::cli::main_with_args`.

use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use snell::film::{Channel, Image, Layer, PixelFormat};
use snell::spectrum::Rgb;
use snell::{LoadOptions, Mode, RenderOptions};
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

pyo3::create_exception!(
    _snell,
    SceneError,
    PyValueError,
    "A scene that cannot be loaded or rendered: `file`, `line`, `column` say where (None when unknown), `str(e)` is the message the command line prints."
);

/// How often the calling thread looks for Ctrl-C while a render runs.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Runs `f`, turning a panic into a Python `RuntimeError`.
fn guarded<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|payload| Err(panic_error(payload)))
}

fn panic_error(payload: Box<dyn std::any::Any + Send>) -> PyErr {
    let what = payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_string());
    PyRuntimeError::new_err(format!("internal error in Snell (please report it): {what}"))
}

/// A `snell.SceneError` carrying the location of a located scene error.
fn scene_error(py: Python<'_>, e: &snell::SceneError) -> PyErr {
    let err = SceneError::new_err(e.to_string());
    let value = err.value(py);
    let (file, line, column) = match (&e.location, &e.path) {
        (Some(loc), _) => (Some(loc.file.path.display().to_string()), Some(loc.line), Some(loc.col)),
        (None, Some(p)) => (Some(p.display().to_string()), None, None),
        (None, None) => (None, None, None),
    };
    let _ = value.setattr("file", file);
    let _ = value.setattr("line", line);
    let _ = value.setattr("column", column);
    let _ = value.setattr("message", e.message.clone());
    let _ = value.setattr("help", e.help.clone());
    err
}

/// A render-time error (a mode the scene cannot use, a film above the
/// memory budget) as `snell.SceneError` without a location, worded as the
/// command line prints it.
fn render_error(py: Python<'_>, e: &anyhow::Error, file: Option<&str>) -> PyErr {
    if let Some(se) = e.downcast_ref::<snell::SceneError>() {
        return scene_error(py, se);
    }
    let err = SceneError::new_err(format!("error: {e:#}"));
    let value = err.value(py);
    let _ = value.setattr("file", file.map(str::to_string));
    let _ = value.setattr("line", None::<u32>);
    let _ = value.setattr("column", None::<u32>);
    let _ = value.setattr("message", format!("{e:#}"));
    let _ = value.setattr("help", None::<String>);
    err
}

/// A loaded scene. Renders hold its lock, so two threads rendering the
/// same scene take turns (different scenes render at once).
#[pyclass(module = "snell._snell", name = "NativeScene", frozen)]
struct NativeScene {
    scene: Mutex<snell::Scene>,
    /// The file it came from (for load_string: the name errors use).
    path: String,
}

impl NativeScene {
    fn lock(&self) -> std::sync::MutexGuard<'_, snell::Scene> {
        self.scene.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

#[pymethods]
impl NativeScene {
    #[getter]
    fn path(&self) -> String {
        self.path.clone()
    }

    /// (width, height) of the full film.
    #[getter]
    fn film_size(&self) -> (u32, u32) {
        let s = self.lock();
        (s.film.width, s.film.height)
    }

    /// (x, y, width, height) of the rendered window; width × height is the image size.
    #[getter]
    fn crop(&self) -> (u32, u32, u32, u32) {
        let [x, y, w, h] = self.lock().film.crop;
        (x, y, w, h)
    }

    #[getter]
    fn pixel_format(&self) -> &'static str {
        let f = self.lock().film.pixel_format;
        PixelFormat::NAMES[pixel_format_index(f)]
    }

    #[getter]
    fn spp(&self) -> u32 {
        self.lock().sampler.sample_count
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.lock().sampler.seed
    }

    #[getter]
    fn sensor(&self) -> &'static str {
        match self.lock().camera {
            snell::sensor::Camera::Perspective(_) => "perspective",
            snell::sensor::Camera::Orthographic(_) => "orthographic",
            snell::sensor::Camera::ThinLens(_) => "thinlens",
            snell::sensor::Camera::RadianceMeter(_) => "radiancemeter",
            snell::sensor::Camera::IrradianceMeter(_) => "irradiancemeter",
            snell::sensor::Camera::Distant(_) => "distant",
            // Sensors added to the renderer later.
            #[allow(unreachable_patterns)]
            _ => "other",
        }
    }

    #[getter]
    fn integrator(&self) -> &'static str {
        use snell::integrator::Integrator as I;
        match self.lock().integrator {
            I::Direct(_) => "direct",
            I::Path(_) => "path",
            I::Particle(_) => "ptracer",
            I::Aov(_) => "aov",
            I::Moment(_) => "moment",
            I::VolPath(_) => "volpath",
            #[allow(unreachable_patterns)]
            _ => "other",
        }
    }

    #[getter]
    fn emitters(&self) -> Vec<&'static str> {
        use snell::emitter::Emitter as E;
        self.lock()
            .emitters
            .iter()
            .map(|e| match e {
                E::Area(_) => "area",
                E::Point(_) => "point",
                E::Constant(_) => "constant",
                E::Directional(_) => "directional",
                E::Spot(_) => "spot",
                E::EnvMap(_) => "envmap",
                E::Projector(_) => "projector",
                #[allow(unreachable_patterns)]
                _ => "other",
            })
            .collect()
    }

    /// One (geometry, bsdf plugin, emits) triple per shape; meshes
    /// (rectangle, cube, obj, ply, serialized) are all "mesh".
    #[getter]
    fn shapes(&self) -> Vec<(&'static str, &'static str, bool)> {
        use snell::geometry::shape::ShapeGeometry as G;
        let s = self.lock();
        s.shapes
            .iter()
            .map(|sh| {
                let geometry = match sh.geometry {
                    G::Mesh(_) => "mesh",
                    G::Sphere(_) => "sphere",
                    G::Disk(_) => "disk",
                    G::Cylinder(_) => "cylinder",
                    #[allow(unreachable_patterns)]
                    _ => "other",
                };
                let bsdf = s.bsdfs.get(sh.bsdf as usize).map_or("none", |b| b.plugin());
                (geometry, bsdf, sh.emitter.is_some())
            })
            .collect()
    }

    #[getter]
    fn bsdfs(&self) -> Vec<&'static str> {
        self.lock().bsdfs.iter().map(|b| b.plugin()).collect()
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.lock().warnings.clone()
    }

    /// The names of the channels `render` returns in `mode`.
    fn channel_names(&self, mode: &str) -> PyResult<Vec<String>> {
        let mode = parse_mode(mode)?;
        let s = self.lock();
        let format = s.film.pixel_format;
        let mut names: Vec<String> = format.colour_channels().iter().map(|c| c.to_string()).collect();
        if format.has_alpha() {
            names.push("A".into());
        }
        names.extend(s.integrator.channel_names());
        if mode.polarized() {
            for layer in ["S0", "S1", "S2", "S3"] {
                names.extend(["R", "G", "B"].iter().map(|c| format!("{layer}.{c}")));
            }
        }
        Ok(names)
    }
}

fn pixel_format_index(f: PixelFormat) -> usize {
    PixelFormat::NAMES.iter().position(|n| PixelFormat::from_name(n) == Some(f)).unwrap_or(0)
}

fn parse_mode(mode: &str) -> PyResult<Mode> {
    Mode::from_name(mode).map_err(|e| PyValueError::new_err(e.to_string()))
}

fn load_options(params: HashMap<String, String>, spp: Option<u32>, seed: Option<u64>) -> LoadOptions {
    LoadOptions { params, spp, seed }
}

/// Loads a Mitsuba 3 XML scene file; `params` are the `-D` values.
#[pyfunction]
#[pyo3(signature = (path, params, spp=None, seed=None))]
fn load_file(py: Python<'_>, path: PathBuf, params: HashMap<String, String>, spp: Option<u32>, seed: Option<u64>) -> PyResult<NativeScene> {
    guarded(|| {
        let options = load_options(params, spp, seed);
        let loaded = py.allow_threads(|| catch_unwind(AssertUnwindSafe(|| snell::load_file(&path, &options))));
        match loaded {
            Ok(Ok(scene)) => Ok(NativeScene { scene: Mutex::new(scene), path: path.display().to_string() }),
            Ok(Err(e)) => Err(scene_error(py, &e)),
            Err(payload) => Err(panic_error(payload)),
        }
    })
}

/// Loads scene text; `path` names it in errors and its folder resolves
/// relative file names.
#[pyfunction]
#[pyo3(signature = (text, path, params, spp=None, seed=None))]
fn load_string(py: Python<'_>, text: String, path: PathBuf, params: HashMap<String, String>, spp: Option<u32>, seed: Option<u64>) -> PyResult<NativeScene> {
    guarded(|| {
        let options = load_options(params, spp, seed);
        let loaded = py.allow_threads(|| catch_unwind(AssertUnwindSafe(|| snell::load_str(&path, &text, &options))));
        match loaded {
            Ok(Ok(scene)) => Ok(NativeScene { scene: Mutex::new(scene), path: path.display().to_string() }),
            Ok(Err(e)) => Err(scene_error(py, &e)),
            Err(payload) => Err(panic_error(payload)),
        }
    })
}

/// The channels of `image` as the EXR writer names them — the pixel
/// format's colour channels, the scalar channels (alpha, AOVs), then, in a
/// polarized render, S0 (the colour again) and the S1–S3 layers — and the
/// pixels interleaved row by row (H × W × C, float32).
fn flatten(image: &Image) -> (Vec<String>, Vec<f32>) {
    let format = image.pixel_format;
    let n = image.pixels.len();
    let mut names: Vec<String> = vec![];
    let mut planes: Vec<Vec<f32>> = vec![];
    for (c, name) in format.colour_channels().iter().enumerate() {
        names.push(name.to_string());
        planes.push(image.pixels.iter().map(|p| format.convert(*p)[c]).collect());
    }
    for Channel { name, values } in &image.channels {
        if name == "A" && !format.has_alpha() {
            continue;
        }
        names.push(name.clone());
        planes.push(values.clone());
    }
    let mut layers: Vec<(&str, &[Rgb])> = vec![];
    if image.layer("S1").is_some() && image.layer("S0").is_none() {
        layers.push(("S0", &image.pixels));
    }
    layers.extend(image.layers.iter().map(|l| (l.name.as_str(), l.pixels.as_slice())));
    for (layer, pixels) in layers {
        for (c, rgb) in ["R", "G", "B"].into_iter().enumerate() {
            names.push(format!("{layer}.{rgb}"));
            planes.push(pixels.iter().map(|p| p[c]).collect());
        }
    }
    let mut data = Vec::with_capacity(n * planes.len());
    for i in 0..n {
        for plane in &planes {
            data.push(plane.get(i).copied().unwrap_or(0.0));
        }
    }
    (names, data)
}

/// The image that [`flatten`] would give `data` with channel `names`.
fn unflatten(width: u32, height: u32, names: &[String], data: &[f32]) -> anyhow::Result<Image> {
    let c = names.len();
    let n = width as usize * height as usize;
    if c == 0 || data.len() != n * c {
        anyhow::bail!("{} values do not make a {height} × {width} image of {c} channels", data.len());
    }
    let plane = |k: usize| -> Vec<f32> { (0..n).map(|i| data[i * c + k]).collect() };
    let find = |name: &str| names.iter().position(|s| s == name);
    let rgb_of = |r: usize, g: usize, b: usize| -> Vec<Rgb> { (0..n).map(|i| Rgb::new(data[i * c + r], data[i * c + g], data[i * c + b])).collect() };
    let mut used = vec![false; c];
    let (pixels, format) = match (find("R"), find("G"), find("B"), find("Y")) {
        (Some(r), Some(g), Some(b), _) => {
            used[r] = true;
            used[g] = true;
            used[b] = true;
            (rgb_of(r, g, b), if find("A").is_some() { PixelFormat::Rgba } else { PixelFormat::Rgb })
        }
        (_, _, _, Some(y)) => {
            used[y] = true;
            let v = plane(y);
            (v.iter().map(|&v| Rgb::new(v, v, v)).collect(), if find("A").is_some() { PixelFormat::LuminanceAlpha } else { PixelFormat::Luminance })
        }
        _ => anyhow::bail!("the channels {names:?} have no R, G, B (or Y) to make the image of"),
    };
    let mut image = Image::new(width, height, pixels);
    image.pixel_format = format;
    // Complete NAME.R/G/B triples are layers (S0 is the colour again and is
    // written from it); the rest are scalar channels.
    let mut layer_names: Vec<String> = vec![];
    for name in names {
        if let Some(prefix) = name.strip_suffix(".R")
            && !layer_names.iter().any(|l| l == prefix)
        {
            layer_names.push(prefix.to_string());
        }
    }
    for prefix in layer_names {
        if let (Some(r), Some(g), Some(b)) = (find(&format!("{prefix}.R")), find(&format!("{prefix}.G")), find(&format!("{prefix}.B"))) {
            used[r] = true;
            used[g] = true;
            used[b] = true;
            if prefix != "S0" {
                image.layers.push(Layer { name: prefix, pixels: rgb_of(r, g, b) });
            }
        }
    }
    for (k, name) in names.iter().enumerate() {
        if !used[k] {
            image.channels.push(Channel { name: name.clone(), values: plane(k) });
        }
    }
    Ok(image)
}

fn image_bytes(data: &[f32]) -> Vec<u8> {
    data.iter().flat_map(|v| v.to_ne_bytes()).collect()
}

/// What a render hands back: pixels (H × W × C float32, native byte
/// order), height, width, channel names, and whether it was stopped early.
type RenderResult = (Py<PyBytes>, u32, u32, Vec<String>, bool);

/// Renders `scene` in `mode`. The render runs on a thread of its own with
/// the GIL released; the calling thread wakes every 50 ms to run Python's
/// signal handlers, and on KeyboardInterrupt (or any exception from a
/// handler or from `on_pass`) sets the render's stop flag, waits for the
/// work under way, and raises that exception. `on_pass(fraction, data,
/// height, width, names)` is called after each pass.
#[pyfunction]
#[pyo3(signature = (scene, mode, spp=None, seed=None, threads=0, passes=1, on_pass=None))]
#[allow(clippy::too_many_arguments)]
fn render(
    py: Python<'_>,
    scene: &NativeScene,
    mode: &str,
    spp: Option<u32>,
    seed: Option<u64>,
    threads: usize,
    passes: u32,
    on_pass: Option<PyObject>,
) -> PyResult<RenderResult> {
    guarded(|| {
        let mode = parse_mode(mode)?;
        if let Some(n) = spp
            && !(1..=snell::scene::loader::MAX_SPP).contains(&n)
        {
            return Err(PyValueError::new_err(format!("spp={n} is not between 1 and {} (2^24)", snell::scene::loader::MAX_SPP)));
        }
        let stop = Arc::new(AtomicBool::new(false));
        // `..default()` keeps this building when RenderOptions gains fields.
        #[allow(clippy::needless_update)]
        let options = RenderOptions { threads, progress: false, stop: Some(stop.clone()), passes: passes.max(1), ..RenderOptions::default() };
        // An exception raised by on_pass, kept to raise once the render ends.
        let callback_error: Mutex<Option<PyErr>> = Mutex::new(None);
        let (tx, rx) = mpsc::channel();
        // Behind a mutex only to be Sync for allow_threads; one thread uses it.
        let rx = Mutex::new(rx);
        let mut interrupt: Option<PyErr> = None;
        let outcome = std::thread::scope(|s| {
            let worker_stop = stop.clone();
            let (callback_error, on_pass, options) = (&callback_error, &on_pass, &options);
            s.spawn(move || {
                let result = catch_unwind(AssertUnwindSafe(|| {
                    let what = scene.path.clone();
                    let mut scene = scene.lock();
                    let saved = (scene.sampler.sample_count, scene.sampler.seed);
                    if let Some(n) = spp {
                        // Rounded as the sampler rounds it (as --spp is).
                        scene.sampler.set_sample_count(n);
                    }
                    if let Some(seed) = seed {
                        scene.sampler.seed = seed;
                    }
                    let mut report = |r: &snell::PassReport| {
                        let Some(cb) = on_pass else { return };
                        let (names, data) = flatten(r.image);
                        let fraction = r.spp_done as f64 / r.spp_total.max(1) as f64;
                        let (w, h) = (r.image.width, r.image.height);
                        Python::with_gil(|py| {
                            let bytes = PyBytes::new(py, &image_bytes(&data));
                            if let Err(e) = cb.call1(py, (fraction, bytes, h, w, names)) {
                                worker_stop.store(true, Ordering::SeqCst);
                                let mut slot = callback_error.lock().unwrap_or_else(|p| p.into_inner());
                                slot.get_or_insert(e);
                            }
                        });
                    };
                    let result = snell::session::prepare(&scene, mode, &what)
                        .and_then(|()| snell::session::render(&scene, mode, options, &mut report));
                    (scene.sampler.sample_count, scene.sampler.seed) = saved;
                    result.map(|(image, stats)| {
                        let (names, data) = flatten(&image);
                        (image.width, image.height, names, data, stats.interrupted)
                    })
                }));
                let _ = tx.send(result);
            });
            loop {
                match py.allow_threads(|| rx.lock().unwrap_or_else(|p| p.into_inner()).recv_timeout(SIGNAL_POLL)) {
                    Ok(result) => break Some(result),
                    Err(mpsc::RecvTimeoutError::Disconnected) => break None,
                    Err(mpsc::RecvTimeoutError::Timeout) => {
                        if interrupt.is_none()
                            && let Err(e) = py.check_signals()
                        {
                            stop.store(true, Ordering::SeqCst);
                            interrupt = Some(e);
                        }
                    }
                }
            }
        });
        if let Some(e) = interrupt {
            return Err(e);
        }
        if let Some(e) = callback_error.lock().unwrap_or_else(|p| p.into_inner()).take() {
            return Err(e);
        }
        match outcome {
            Some(Ok(Ok((w, h, names, data, interrupted)))) => Ok((PyBytes::new(py, &image_bytes(&data)).unbind(), h, w, names, interrupted)),
            Some(Ok(Err(e))) => Err(render_error(py, &e, Some(&scene.path))),
            Some(Err(payload)) => Err(panic_error(payload)),
            None => Err(PyRuntimeError::new_err("internal error in Snell: the render thread ended without a result")),
        }
    })
}

/// Renders samples [`start`, `end`) of every pixel of `scene` in `mode` and
/// returns their exact film state (`snell::FilmState::to_bytes`): the unit
/// of work of a distributed render. States of disjoint ranges merge exactly
/// ([`state_merge`]), so any split of the samples over tasks and machines
/// gives the image of one render, bit for bit. The GIL is released.
///
/// With `tile` = (x, y, width, height) in crop-window coordinates, renders
/// only that tile's pixels: its state keeps the sums of the tile and of the
/// border the filter spreads its samples into, and the states of tiles
/// covering the window add up exactly ([`state_merge_tiles`]).
#[pyfunction]
#[pyo3(signature = (scene, mode, start, end, threads=0, tile=None))]
#[allow(clippy::too_many_arguments)]
fn render_samples(py: Python<'_>, scene: &NativeScene, mode: &str, start: u32, end: u32, threads: usize, tile: Option<(u32, u32, u32, u32)>) -> PyResult<Py<PyBytes>> {
    guarded(|| {
        let mode = parse_mode(mode)?;
        let scene_ref = scene.lock();
        let spp = scene_ref.sampler.sample_count;
        if !(start < end && end <= spp) {
            return Err(PyValueError::new_err(format!("samples [{start}, {end}) are not a range within the scene's {spp} samples per pixel")));
        }
        #[allow(clippy::needless_update)]
        let options = RenderOptions { threads, progress: false, ..RenderOptions::default() };
        let what = scene.path.clone();
        let result = py.allow_threads(|| {
            catch_unwind(AssertUnwindSafe(|| {
                snell::session::prepare(&scene_ref, mode, &what)
                    .and_then(|()| match tile {
                        Some((x, y, w, h)) => snell::session::render_tile_samples(&scene_ref, mode, &options, start..end, [x, y, w, h]),
                        None => snell::session::render_samples(&scene_ref, mode, &options, start..end),
                    })
                    .map(|state| state.to_bytes())
            }))
        });
        drop(scene_ref);
        match result {
            Ok(Ok(bytes)) => Ok(PyBytes::new(py, &bytes).unbind()),
            Ok(Err(e)) => Err(render_error(py, &e, Some(&scene.path))),
            Err(payload) => Err(panic_error(payload)),
        }
    })
}

fn film_state(bytes: &[u8]) -> PyResult<snell::film::FilmState> {
    snell::film::FilmState::from_bytes(bytes).map_err(|e| PyValueError::new_err(format!("not a Snell film state: {e:#}")))
}

/// The exact sum of two film states of disjoint sample ranges of the same
/// render (an error for overlapping ranges or another scene, seed or mode).
#[pyfunction]
fn state_merge(py: Python<'_>, a: &[u8], b: &[u8]) -> PyResult<Py<PyBytes>> {
    guarded(|| {
        let (mut a, b) = (film_state(a)?, film_state(b)?);
        py.allow_threads(|| a.merge(&b)).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
        Ok(PyBytes::new(py, &a.to_bytes()).unbind())
    })
}

/// The image of a film state, as [`render`] returns images.
#[pyfunction]
fn state_develop(py: Python<'_>, state: &[u8]) -> PyResult<RenderResult> {
    guarded(|| {
        let state = film_state(state)?;
        let image = py.allow_threads(|| state.develop());
        let (names, data) = flatten(&image);
        Ok((PyBytes::new(py, &image_bytes(&data)).unbind(), image.height, image.width, names, !state.is_finished()))
    })
}

/// What a film state holds: its sample ranges, the render's samples per
/// pixel, and whether every pixel has every sample of the ranges.
#[pyfunction]
fn state_info(state: &[u8]) -> PyResult<(Vec<(u32, u32)>, u32, bool)> {
    guarded(|| {
        let state = film_state(state)?;
        Ok((state.ranges().iter().map(|r| (r.start, r.end)).collect(), state.header.sample_count, state.header.complete))
    })
}

/// Writes H × W × C float32 `data` with channel `names` to `path` (.exr with
/// every channel; .png 8-bit sRGB and .pfm hold the colour only).
#[pyfunction]
fn write(py: Python<'_>, data: &[u8], height: u32, width: u32, names: Vec<String>, path: PathBuf) -> PyResult<()> {
    guarded(|| {
        let values: Vec<f32> = data.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect();
        let image = unflatten(width, height, &names, &values).map_err(|e| PyValueError::new_err(e.to_string()))?;
        py.allow_threads(|| snell::film::output::write_image(&image, &path)).map_err(|e| PyOSError::new_err(format!("{e:#}")))
    })
}

/// Reads an image: EXR (every channel, named as `write` names them), PFM
/// (linear colour) or PNG/JPEG (8-bit values scaled to [0, 1], not
/// linearised). Returns (data, height, width, names).
#[pyfunction]
fn read(py: Python<'_>, path: PathBuf) -> PyResult<RenderResult> {
    guarded(|| {
        let image = py.allow_threads(|| read_image(&path)).map_err(|e| PyOSError::new_err(format!("{e:#}")))?;
        let (names, data) = flatten(&image);
        Ok((PyBytes::new(py, &image_bytes(&data)).unbind(), image.height, image.width, names, false))
    })
}

fn read_image(path: &Path) -> anyhow::Result<Image> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).unwrap_or_default();
    match ext.as_str() {
        "exr" => snell::film::output::read_exr(path),
        "pfm" => read_pfm(path),
        "png" | "jpg" | "jpeg" => {
            let img = image::open(path).map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?.to_rgb32f();
            let (w, h) = img.dimensions();
            let pixels = img.pixels().map(|p| Rgb::new(p[0], p[1], p[2])).collect();
            Ok(Image::new(w, h, pixels))
        }
        _ => anyhow::bail!("cannot tell the image format of {}: use .exr, .pfm or .png", path.display()),
    }
}

/// PFM (`PF` colour or `Pf` grey, either byte order; rows bottom first).
fn read_pfm(path: &Path) -> anyhow::Result<Image> {
    let bytes = std::fs::read(path).map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    let bad = || anyhow::anyhow!("{} is not a PFM image", path.display());
    let mut fields = vec![];
    let mut pos = 0;
    while fields.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err(bad());
        }
        fields.push(std::str::from_utf8(&bytes[start..pos]).map_err(|_| bad())?.to_string());
    }
    pos += 1;
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(bad()),
    };
    let w: usize = fields[1].parse().map_err(|_| bad())?;
    let h: usize = fields[2].parse().map_err(|_| bad())?;
    let scale: f32 = fields[3].parse().map_err(|_| bad())?;
    let count = w.checked_mul(h).and_then(|n| n.checked_mul(channels)).ok_or_else(bad)?;
    let body = bytes.get(pos..pos + count * 4).ok_or_else(bad)?;
    let value = |i: usize| {
        let b = [body[4 * i], body[4 * i + 1], body[4 * i + 2], body[4 * i + 3]];
        if scale < 0.0 { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) }
    };
    let mut pixels = vec![Rgb::BLACK; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = ((h - 1 - y) * w + x) * channels;
            pixels[y * w + x] = if channels == 3 { Rgb::new(value(i), value(i + 1), value(i + 2)) } else { Rgb::new(value(i), value(i), value(i)) };
        }
    }
    let mut image = Image::new(w as u32, h as u32, pixels);
    if channels == 1 {
        image.pixel_format = PixelFormat::Luminance;
    }
    Ok(image)
}

/// Runs the `snell` command line on `args` (program name first) and
/// returns its exit status.
#[pyfunction]
fn cli_main(py: Python<'_>, args: Vec<String>) -> PyResult<u8> {
    guarded(|| {
        let code = py.allow_threads(|| snell::cli::main_with_args(args));
        Ok((0..=255u8).find(|&n| std::process::ExitCode::from(n) == code).unwrap_or(1))
    })
}

/// Adds the states of `tiles` (tiles covering the crop window once, each
/// holding the same sample ranges) to `state` (a state of the whole window,
/// or None: an empty one), exactly: see `FilmState::merge_tiles`.
#[pyfunction]
#[pyo3(signature = (state, tiles))]
fn state_merge_tiles(py: Python<'_>, state: Option<&[u8]>, tiles: Vec<Vec<u8>>) -> PyResult<Py<PyBytes>> {
    guarded(|| {
        let tiles = tiles.iter().map(|t| film_state(t)).collect::<PyResult<Vec<_>>>()?;
        let first = tiles.first().ok_or_else(|| PyValueError::new_err("no tiles to merge"))?;
        let mut state = match state {
            Some(s) => film_state(s)?,
            None => snell::film::FilmState::empty(first.header.clone()),
        };
        py.allow_threads(|| state.merge_tiles(&tiles)).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
        Ok(PyBytes::new(py, &state.to_bytes()).unbind())
    })
}

/// The command line's checkpoints of a render of `scene` in `mode`, the
/// scene's file holding `source` (for a dictionary: its XML), with `-D`
/// definitions `defines` (each NAME=VALUE).
fn checkpoint_of(scene: &NativeScene, source: &[u8], defines: &[String], mode: &str) -> PyResult<snell::cli::Checkpoint> {
    let mode = parse_mode(mode)?;
    Ok(snell::cli::Checkpoint::of(source, defines, &scene.lock(), mode))
}

/// Writes film state `state` to `path` as the command line's checkpoints
/// are written (`--write-every`, `--resume`): an EXR of its image whose
/// header holds the render's identity (`snell.render`) and the exact state
/// (`snell.state`), written atomically. The state is kept even when the
/// render is finished.
#[pyfunction]
fn checkpoint_write(py: Python<'_>, scene: &NativeScene, source: &[u8], defines: Vec<String>, mode: &str, state: &[u8], path: PathBuf) -> PyResult<()> {
    guarded(|| {
        let checkpoint = checkpoint_of(scene, source, &defines, mode)?;
        let state = film_state(state)?;
        py.allow_threads(|| {
            let mut meta = checkpoint.metadata(Some(&state));
            if meta.state.is_none() && state.header.complete {
                meta.state = Some(state.to_bytes());
            }
            snell::film::output::write_image_with(&state.develop(), &path, &meta)
        })
        .map_err(|e| PyOSError::new_err(format!("{e:#}")))
    })
}

/// Reads the checkpoint `path` of a render of `scene` (see
/// [`checkpoint_write`]): (the state's bytes, or None when the file holds
/// no state: a finished render of the command line). A checkpoint of
/// another render (scene file, -D, size, spp, seed or mode) is refused
/// with `ValueError`, as `--resume` refuses it.
#[pyfunction]
fn checkpoint_read(py: Python<'_>, scene: &NativeScene, source: &[u8], defines: Vec<String>, mode: &str, path: PathBuf) -> PyResult<Option<Py<PyBytes>>> {
    guarded(|| {
        let checkpoint = checkpoint_of(scene, source, &defines, mode)?;
        let state = py.allow_threads(|| -> anyhow::Result<Option<Vec<u8>>> {
            Ok(match checkpoint.read(&path)? {
                Some(state) => Some(state.to_bytes()),
                // Finished: the state if the file keeps it.
                None => snell::film::output::read_exr_metadata(&path)?.state,
            })
        });
        match state {
            Ok(s) => Ok(s.map(|b| PyBytes::new(py, &b).unbind())),
            Err(e) => Err(PyValueError::new_err(format!("{e:#}").replace("--resume ", "checkpoint "))),
        }
    })
}

/// The live preview server of `snell render --preview`, for renders that
/// the command line does not run (a distributed render): started on
/// `host`:`port` (0: any free port); `publish` shows an image.
#[pyclass(module = "snell._snell")]
struct Preview {
    server: Mutex<Option<snell::preview::Preview>>,
    stop: Arc<AtomicBool>,
    started: std::time::Instant,
    url: String,
    port: u16,
}

#[pymethods]
impl Preview {
    #[new]
    #[pyo3(signature = (port=0, mode="rgb", width=1, height=1, host="127.0.0.1"))]
    fn new(port: u16, mode: &str, width: u32, height: u32, host: &str) -> PyResult<Preview> {
        guarded(|| {
            let mode = parse_mode(mode)?;
            let ip: std::net::IpAddr = host.parse().map_err(|_| PyValueError::new_err(format!("host={host:?} is not an IP address")))?;
            let stop = Arc::new(AtomicBool::new(false));
            let server = snell::preview::Preview::start((ip, port).into(), mode, width, height, stop.clone()).map_err(|e| PyOSError::new_err(format!("{e:#}")))?;
            let (url, port) = (server.url(), server.addr().port());
            Ok(Preview { server: Mutex::new(Some(server)), stop, started: std::time::Instant::now(), url, port })
        })
    }

    #[getter]
    fn url(&self) -> String {
        self.url.clone()
    }

    #[getter]
    fn port(&self) -> u16 {
        self.port
    }

    /// Whether the page's Stop button was pressed.
    #[getter]
    fn stop_requested(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// Shows the image of film state `state` (bytes) or, with `state` None,
    /// the H × W × C float32 `data` with channel `names`: pass `pass_` of
    /// `passes`, `spp_done` of `spp_total` samples per pixel.
    #[pyo3(signature = (state, data, height, width, names, pass_, passes, spp_done, spp_total))]
    #[allow(clippy::too_many_arguments)]
    fn publish(
        &self,
        py: Python<'_>,
        state: Option<&[u8]>,
        data: Option<&[u8]>,
        height: u32,
        width: u32,
        names: Vec<String>,
        pass_: u32,
        passes: u32,
        spp_done: u32,
        spp_total: u32,
    ) -> PyResult<()> {
        guarded(|| {
            let image = match (state, data) {
                (Some(s), _) => {
                    let s = film_state(s)?;
                    py.allow_threads(|| s.develop())
                }
                (None, Some(d)) => {
                    let values: Vec<f32> = d.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect();
                    unflatten(width, height, &names, &values).map_err(|e| PyValueError::new_err(e.to_string()))?
                }
                (None, None) => return Err(PyValueError::new_err("publish needs a film state or an image")),
            };
            let elapsed = self.started.elapsed().as_secs_f64();
            if let Some(server) = self.server.lock().unwrap_or_else(|p| p.into_inner()).as_ref() {
                server.publish_image(&image, pass_, passes, spp_done, spp_total, elapsed);
            }
            Ok(())
        })
    }

    /// Marks the render as over: stopped early (`interrupted`) or done.
    #[pyo3(signature = (interrupted=false))]
    fn finish(&self, interrupted: bool) {
        if let Some(server) = self.server.lock().unwrap_or_else(|p| p.into_inner()).as_ref() {
            server.finish_as(interrupted);
        }
    }

    /// Stops the server (the page then shows the connection lost).
    fn close(&self) {
        self.server.lock().unwrap_or_else(|p| p.into_inner()).take();
    }
}

#[pymodule]
fn _snell(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add_class::<NativeScene>()?;
    m.add_function(wrap_pyfunction!(load_file, m)?)?;
    m.add_function(wrap_pyfunction!(load_string, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(write, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(cli_main, m)?)?;
    m.add_function(wrap_pyfunction!(render_samples, m)?)?;
    m.add_function(wrap_pyfunction!(state_merge, m)?)?;
    m.add_function(wrap_pyfunction!(state_develop, m)?)?;
    m.add_function(wrap_pyfunction!(state_info, m)?)?;
    m.add_function(wrap_pyfunction!(state_merge_tiles, m)?)?;
    m.add_function(wrap_pyfunction!(checkpoint_write, m)?)?;
    m.add_function(wrap_pyfunction!(checkpoint_read, m)?)?;
    m.add_class::<Preview>()?;
    Ok(())
}
