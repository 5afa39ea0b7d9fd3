//! The preview's HTTP server: shared state that the render thread publishes
//! into, and the threads that answer the page's requests from it.

use super::{encode_image, frame_layers};
use crate::render::{PassReport, RenderStats};
use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::State as Extract;
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::Serialize;
use std::net::{IpAddr, SocketAddr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

/// The page, its script and styles in one file (no build step).
const PAGE: &str = include_str!("page.html");

/// What the page is told about the render's progress.
#[derive(Clone, Debug, Default, Serialize)]
struct Progress {
    mode: String,
    width: u32,
    height: u32,
    layers: Vec<&'static str>,
    /// The last pass finished (0: none yet) and the number planned.
    pass: u32,
    passes: u32,
    spp_done: u32,
    spp_total: u32,
    /// Seconds from the first pass's start to the end of the last pass.
    pass_seconds: f64,
    /// Pixel samples per second so far (all passes).
    samples_per_second: f64,
    /// "starting", "rendering", "stopping", "done" or "stopped".
    state: &'static str,
}

struct State {
    progress: Progress,
    /// The latest encoded pass (reference-counted: every request that
    /// sends it shares the one buffer).
    frame: Option<Bytes>,
    /// When the last pass was published (for the live ETA).
    published: Option<Instant>,
}

struct Shared {
    state: Mutex<State>,
    stop: Arc<AtomicBool>,
    started: Instant,
    /// Whether only loopback Host names are accepted (the server listens on loopback).
    loopback: bool,
}

impl Shared {
    /// The state, even if a request handler panicked while holding it.
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// A running preview server (a thread of its own running an async HTTP
/// server: idle, slow or stalled connections cost it memory, not threads).
/// Dropping it stops the server.
pub struct Preview {
    shared: Arc<Shared>,
    addr: SocketAddr,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
}

impl Preview {
    /// Starts serving on `addr` (port 0: any free port) for a render in
    /// `mode` of a `width` × `height` film; `stop` is the flag that ends the
    /// render (set by the page's Stop button).
    pub fn start(addr: SocketAddr, mode: crate::Mode, width: u32, height: u32, stop: Arc<AtomicBool>) -> anyhow::Result<Preview> {
        let listener = std::net::TcpListener::bind(addr).map_err(|e| {
            anyhow::anyhow!("cannot serve the preview on {addr}: {e} (choose another port with --preview PORT, or 0 for any free one)")
        })?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let progress = Progress {
            mode: mode.name().to_string(),
            width,
            height,
            layers: if mode.polarized() { vec!["S0", "S1", "S2", "S3"] } else { vec!["S0"] },
            state: "starting",
            ..Progress::default()
        };
        let shared = Arc::new(Shared {
            state: Mutex::new(State { progress, frame: None, published: None }),
            stop,
            started: Instant::now(),
            loopback: addr.ip().is_loopback(),
        });
        let app = Router::new()
            .route("/", get(serve_page))
            .route("/index.html", get(serve_page))
            .route("/progress", get(serve_progress))
            .route("/image", get(serve_image))
            .route("/stop", post(stop_render))
            .fallback(not_found)
            .with_state(shared.clone());
        let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
        let (shutdown, signal) = tokio::sync::oneshot::channel::<()>();
        std::thread::Builder::new().name("snell-preview".into()).spawn(move || {
            runtime.block_on(async move {
                let Ok(listener) = tokio::net::TcpListener::from_std(listener) else { return };
                let _ = axum::serve(listener, app)
                    .with_graceful_shutdown(async move {
                        let _ = signal.await;
                    })
                    .await;
            });
        })?;
        Ok(Preview { shared, addr, shutdown: Some(shutdown) })
    }

    /// The address the server listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's address.
    pub fn url(&self) -> String {
        let host = match self.addr.ip() {
            IpAddr::V4(ip) if ip.is_unspecified() => "127.0.0.1".to_string(),
            IpAddr::V6(ip) if ip.is_unspecified() => "[::1]".to_string(),
            IpAddr::V4(ip) => ip.to_string(),
            IpAddr::V6(ip) => format!("[{ip}]"),
        };
        format!("http://{host}:{}/", self.addr.port())
    }

    /// Makes `report`'s pass the one the page shows. Encodes the image (a
    /// copy of its floats) and swaps it in; never waits on a client.
    pub fn publish(&self, report: &PassReport) {
        self.publish_image(report.image, report.pass, report.passes, report.spp_done, report.spp_total, report.elapsed_seconds);
    }

    /// [`Preview::publish`] of an image that no [`PassReport`] carries (a
    /// distributed render's): pass `pass` of `passes`, `spp_done` of
    /// `spp_total` samples per pixel, `elapsed_seconds` since the render began.
    pub fn publish_image(&self, image: &crate::film::Image, pass: u32, passes: u32, spp_done: u32, spp_total: u32, elapsed_seconds: f64) {
        let frame = Bytes::from(encode_image(image, pass, passes, spp_done));
        let pixels = image.width as f64 * image.height as f64;
        let rate = if elapsed_seconds > 0.0 { pixels * spp_done as f64 / elapsed_seconds } else { 0.0 };
        let stopping = self.shared.stop.load(Ordering::Relaxed);
        let mut state = self.shared.lock();
        let p = &mut state.progress;
        p.width = image.width;
        p.height = image.height;
        p.layers = frame_layers(image);
        p.pass = pass;
        p.passes = passes;
        p.spp_done = spp_done;
        p.spp_total = spp_total;
        p.pass_seconds = elapsed_seconds;
        p.samples_per_second = rate;
        p.state = if stopping { "stopping" } else { "rendering" };
        state.frame = Some(frame);
        state.published = Some(Instant::now());
    }

    /// Marks the render as over (its outputs written).
    pub fn finish(&self, stats: &RenderStats) {
        self.finish_as(stats.interrupted);
    }

    /// Marks the render as over: stopped early (`interrupted`) or done.
    pub fn finish_as(&self, interrupted: bool) {
        self.shared.lock().progress.state = if interrupted { "stopped" } else { "done" };
    }
}

impl Drop for Preview {
    fn drop(&mut self) {
        if let Some(s) = self.shutdown.take() {
            let _ = s.send(());
        }
    }
}

/// The shared state, as a handler receives it.
type Shared_ = Extract<Arc<Shared>>;

fn text(code: StatusCode, body: &'static str) -> Response {
    (code, [(header::CACHE_CONTROL, "no-store")], format!("{body}\n")).into_response()
}

/// Whether a Host header names this machine (loopback), so that a page on
/// another site cannot reach the server through DNS rebinding.
fn loopback_host(host: &str) -> bool {
    let name = if let Some(rest) = host.strip_prefix('[') {
        rest.split(']').next().unwrap_or("")
    } else {
        host.rsplit_once(':').map_or(host, |(h, port)| if port.chars().all(|c| c.is_ascii_digit()) { h } else { host })
    };
    name.eq_ignore_ascii_case("localhost") || name.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

fn host(headers: &HeaderMap) -> &str {
    headers.get(header::HOST).and_then(|h| h.to_str().ok()).unwrap_or("")
}

/// 403 for a request addressed to another name than this machine's (when
/// the server listens on loopback).
fn refuse(shared: &Shared, headers: &HeaderMap) -> Option<Response> {
    (shared.loopback && !loopback_host(host(headers)))
        .then(|| text(StatusCode::FORBIDDEN, "the preview answers only requests addressed to this machine (localhost)"))
}

async fn serve_page(Extract(shared): Shared_, headers: HeaderMap) -> Response {
    if let Some(r) = refuse(&shared, &headers) {
        return r;
    }
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8"), (header::CACHE_CONTROL, "no-store")], PAGE).into_response()
}

async fn serve_progress(Extract(shared): Shared_, headers: HeaderMap) -> Response {
    if let Some(r) = refuse(&shared, &headers) {
        return r;
    }
    ([(header::CONTENT_TYPE, "application/json"), (header::CACHE_CONTROL, "no-store")], progress_json(&shared)).into_response()
}

async fn serve_image(Extract(shared): Shared_, headers: HeaderMap) -> Response {
    if let Some(r) = refuse(&shared, &headers) {
        return r;
    }
    let frame = shared.lock().frame.clone();
    match frame {
        None => (StatusCode::SERVICE_UNAVAILABLE, [(header::RETRY_AFTER, "1"), (header::CACHE_CONTROL, "no-store")], "no pass rendered yet\n").into_response(),
        Some(frame) => {
            ([(header::CONTENT_TYPE, "application/octet-stream"), (header::CACHE_CONTROL, "no-store")], Body::from(frame)).into_response()
        }
    }
}

async fn stop_render(Extract(shared): Shared_, headers: HeaderMap) -> Response {
    if let Some(r) = refuse(&shared, &headers) {
        return r;
    }
    // A form or script on another site must not stop the render.
    let origin = headers.get(header::ORIGIN).map(|o| o.to_str().unwrap_or("invalid"));
    if origin.is_some_and(|o| o.split_once("://").map(|(_, h)| h) != Some(host(&headers))) {
        return text(StatusCode::FORBIDDEN, "Stop is accepted only from the preview page itself");
    }
    shared.stop.store(true, Ordering::SeqCst);
    shared.lock().progress.state = "stopping";
    let mut r = (StatusCode::ACCEPTED, "{\"stopping\":true}\n").into_response();
    r.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static("application/json"));
    r
}

async fn not_found() -> Response {
    text(StatusCode::NOT_FOUND, "not found")
}

/// The progress as JSON, with the time since the render began and an
/// estimate of the time left (from the sampling rate so far).
fn progress_json(shared: &Shared) -> String {
    let (progress, published) = {
        let s = shared.lock();
        (s.progress.clone(), s.published)
    };
    let over = matches!(progress.state, "done" | "stopped");
    let elapsed = if over { progress.pass_seconds } else { shared.started.elapsed().as_secs_f64() };
    let pixels = progress.width as f64 * progress.height as f64;
    let left = pixels * progress.spp_total.saturating_sub(progress.spp_done) as f64;
    let eta = match published {
        _ if over => Some(0.0),
        Some(at) if progress.samples_per_second > 0.0 => {
            Some((left / progress.samples_per_second - at.elapsed().as_secs_f64()).max(0.0))
        }
        _ => None,
    };
    let mut json = serde_json::to_value(&progress).unwrap_or_default();
    json["elapsed_seconds"] = elapsed.into();
    json["eta_seconds"] = eta.map_or(serde_json::Value::Null, Into::into);
    json.to_string()
}
