//! The live preview's server (`snell::preview`): started on an ephemeral
//! loopback port and spoken to with plain `TcpStream`s — the page, progress,
//! image and stop endpoints, 404s and 405s, malformed and hostile requests,
//! many clients at once, and a real progressive render published through it.

use snell::film::{Image, Layer};
use snell::preview::{FRAME_HEADER, FRAME_MAGIC, Preview};
use snell::spectrum::Rgb;
use snell::{Mode, PassReport, RenderOptions};
use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

fn start(mode: Mode, w: u32, h: u32) -> (Preview, Arc<AtomicBool>) {
    let stop = Arc::new(AtomicBool::new(false));
    let p = Preview::start("127.0.0.1:0".parse().unwrap(), mode, w, h, stop.clone()).expect("the preview starts");
    (p, stop)
}

struct Reply {
    status: u16,
    head: String,
    body: Vec<u8>,
}

impl Reply {
    fn header(&self, name: &str) -> Option<&str> {
        self.head.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.trim().eq_ignore_ascii_case(name).then(|| v.trim())
        })
    }
    fn json(&self) -> serde_json::Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&self.body)))
    }
}

/// Sends `raw` bytes and reads the whole reply (the server closes after it,
/// as every request says `Connection: close`).
fn raw(addr: SocketAddr, raw: &[u8]) -> Reply {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    s.write_all(raw).unwrap();
    let mut buf = vec![];
    s.read_to_end(&mut buf).unwrap();
    let split = buf.windows(4).position(|w| w == b"\r\n\r\n").unwrap_or_else(|| panic!("no HTTP head in {:?}", String::from_utf8_lossy(&buf)));
    let head = String::from_utf8_lossy(&buf[..split]).to_string();
    let status = head.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    let mut body = buf[split + 4..].to_vec();
    if head.to_ascii_lowercase().contains("transfer-encoding: chunked") {
        body = dechunk(&body);
    }
    Reply { status, head, body }
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = vec![];
    loop {
        let eol = b.windows(2).position(|w| w == b"\r\n").expect("chunk size line");
        let n = usize::from_str_radix(std::str::from_utf8(&b[..eol]).unwrap().split(';').next().unwrap().trim(), 16).unwrap();
        if n == 0 {
            return out;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + n]);
        b = &b[eol + 4 + n..];
    }
}

fn request(addr: SocketAddr, method: &str, path: &str) -> Reply {
    raw(addr, format!("{method} {path} HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nConnection: close\r\n\r\n", addr.port()).as_bytes())
}

fn get(addr: SocketAddr, path: &str) -> Reply {
    request(addr, "GET", path)
}

/// An image whose every value differs, with Stokes layers if `stokes`.
fn test_image(w: u32, h: u32, stokes: bool, salt: f32) -> Image {
    let px = |k: f32| (0..w * h).map(|i| Rgb::new(i as f32 + salt + k, -(i as f32) * 0.5 - k, 1e-3 * i as f32 + k)).collect::<Vec<_>>();
    let mut image = Image::new(w, h, px(0.0));
    if stokes {
        for (k, name) in ["S1", "S2", "S3"].iter().enumerate() {
            image.layers.push(Layer { name: name.to_string(), pixels: px(0.25 * (k + 1) as f32) });
        }
    }
    image
}

/// An empty film state: the preview reads only the report's image and figures.
fn no_state() -> &'static snell::film::FilmState {
    static STATE: std::sync::OnceLock<snell::film::FilmState> = std::sync::OnceLock::new();
    STATE.get_or_init(|| {
        snell::film::FilmState::empty(snell::film::accumulator::StateHeader {
            film_size: [1, 1],
            crop: [0, 0, 1, 1],
            seed: 0,
            sample_count: 16,
            fingerprint: 0,
            pixel_format: "rgb".into(),
            layout: snell::film::accumulator::Layout { camera: true, splats: false, stokes: false, extra: vec![] },
            ranges: vec![],
            complete: true,
            samples_taken: 0,
            invalid_samples: 0,
            radiance_scale: 1.0,
        })
    })
}

fn report(image: &Image, pass: u32) -> PassReport<'_> {
    PassReport { pass, passes: 4, spp_done: 1 << pass, spp_total: 16, elapsed_seconds: pass as f64 * 0.5, image, state: no_state(), active_fraction: 1.0 }
}

/// Decodes a frame: (width, height, layers, pass, floats).
fn decode(body: &[u8]) -> (u32, u32, u32, u32, Vec<f32>) {
    assert!(body.len() >= FRAME_HEADER && &body[..4] == FRAME_MAGIC, "not a frame");
    let u = |i: usize| u32::from_le_bytes(body[4 + 4 * i..8 + 4 * i].try_into().unwrap());
    assert_eq!(u(0), 1, "frame version");
    let floats = body[FRAME_HEADER..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    (u(1), u(2), u(3), u(4), floats)
}

fn flatten(image: &Image) -> Vec<f32> {
    let mut v: Vec<f32> = image.pixels.iter().flat_map(|p| [p[0], p[1], p[2]]).collect();
    for l in &image.layers {
        v.extend(l.pixels.iter().flat_map(|p| [p[0], p[1], p[2]]));
    }
    v
}

#[test]
fn page_progress_and_image_endpoints() {
    let (p, stop) = start(Mode::Rgb, 5, 3);
    let addr = p.addr();
    assert!(addr.ip().is_loopback() && addr.port() != 0);
    assert_eq!(p.url(), format!("http://127.0.0.1:{}/", addr.port()));

    for path in ["/", "/index.html", "/?tab=2"] {
        let page = get(addr, path);
        assert_eq!(page.status, 200, "{path}");
        assert!(page.header("Content-Type").unwrap().starts_with("text/html"));
        let html = String::from_utf8(page.body).unwrap();
        assert!(html.contains("<canvas") && html.contains("id=\"stop\"") && html.contains("fetch(\"image\""), "{path}");
    }

    let before = get(addr, "/progress");
    assert_eq!(before.status, 200);
    let j = before.json();
    assert_eq!((j["state"].as_str(), j["pass"].as_u64(), j["width"].as_u64(), j["mode"].as_str()), (Some("starting"), Some(0), Some(5), Some("rgb")));
    assert_eq!(j["layers"], serde_json::json!(["S0"]));
    assert_eq!(get(addr, "/image").status, 503, "no image before the first pass");

    let first = test_image(5, 3, false, 0.0);
    p.publish(&report(&first, 1));
    let img = get(addr, "/image");
    assert_eq!(img.status, 200);
    assert_eq!(img.header("Content-Type"), Some("application/octet-stream"));
    let (w, h, layers, pass, floats) = decode(&img.body);
    assert_eq!((w, h, layers, pass), (5, 3, 1, 1));
    assert_eq!(floats, flatten(&first), "the floats arrive bit for bit");

    let second = test_image(5, 3, false, 100.0);
    p.publish(&report(&second, 2));
    let j = get(addr, "/progress").json();
    assert_eq!((j["pass"].as_u64(), j["passes"].as_u64(), j["spp_done"].as_u64(), j["spp_total"].as_u64()), (Some(2), Some(4), Some(4), Some(16)));
    assert_eq!(j["state"], "rendering");
    // 15 pixels × 4 spp in 1 s; 15 × 12 samples left at that rate take 3 s at most.
    assert!((j["samples_per_second"].as_f64().unwrap() - 60.0).abs() < 1e-9, "{j}");
    let eta = j["eta_seconds"].as_f64().unwrap();
    assert!(eta > 0.0 && eta <= 3.0, "{j}");
    assert!(j["elapsed_seconds"].as_f64().unwrap() >= 0.0);
    assert_eq!(decode(&get(addr, "/image").body).4, flatten(&second), "the latest pass is served");

    // HEAD gives the head only.
    let head = request(addr, "HEAD", "/image");
    assert_eq!(head.status, 200);
    assert!(head.body.is_empty());
    assert!(!stop.load(Ordering::SeqCst), "reading never stops the render");
}

#[test]
fn polarized_frames_carry_s0_to_s3() {
    let (p, _) = start(Mode::RgbPolarized, 4, 2);
    assert_eq!(get(p.addr(), "/progress").json()["layers"], serde_json::json!(["S0", "S1", "S2", "S3"]));
    let image = test_image(4, 2, true, 7.0);
    p.publish(&report(&image, 1));
    let (w, h, layers, _, floats) = decode(&get(p.addr(), "/image").body);
    assert_eq!((w, h, layers), (4, 2, 4));
    assert_eq!(floats.len(), 4 * 4 * 2 * 3);
    assert_eq!(floats, flatten(&image));
}

#[test]
fn stop_is_a_post_from_the_page_only() {
    let (p, stop) = start(Mode::Rgb, 2, 2);
    let addr = p.addr();
    assert_eq!(get(addr, "/stop").status, 405);
    assert_eq!(get(addr, "/stop").header("Allow"), Some("POST"));
    assert!(!stop.load(Ordering::SeqCst));
    // Another site's form or script: refused.
    let port = addr.port();
    let cross = raw(addr, format!("POST /stop HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nOrigin: http://evil.example\r\nContent-Length: 0\r\nConnection: close\r\n\r\n").as_bytes());
    assert_eq!(cross.status, 403);
    let null = raw(addr, format!("POST /stop HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nOrigin: null\r\nContent-Length: 0\r\nConnection: close\r\n\r\n").as_bytes());
    assert_eq!(null.status, 403);
    // A DNS-rebinding Host.
    let rebound = raw(addr, b"POST /stop HTTP/1.1\r\nHost: evil.example\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
    assert_eq!(rebound.status, 403);
    assert!(!stop.load(Ordering::SeqCst), "refused requests leave the flag alone");

    // The page's own request.
    let ok = raw(addr, format!("POST /stop HTTP/1.1\r\nHost: localhost:{port}\r\nOrigin: http://localhost:{port}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n").as_bytes());
    assert_eq!(ok.status, 202);
    assert!(stop.load(Ordering::SeqCst));
    assert_eq!(get(addr, "/progress").json()["state"], "stopping");
}

#[test]
fn anything_else_is_404_or_405() {
    let (p, stop) = start(Mode::Rgb, 2, 2);
    let addr = p.addr();
    for path in ["/etc/passwd", "/../Cargo.toml", "/index.htm", "/image/", "/image/1", "/progress.json", "/favicon.ico", "//", "/%2e%2e/", "/stop/now", "*"] {
        assert_eq!(get(addr, path).status, 404, "{path}");
    }
    for (method, path) in [("POST", "/image"), ("PUT", "/"), ("DELETE", "/progress"), ("PUT", "/stop"), ("OPTIONS", "/stop")] {
        assert_eq!(request(addr, method, path).status, 405, "{method} {path}");
    }
    assert_eq!(request(addr, "DELETE", "/nothing").status, 404);
    assert!(!stop.load(Ordering::SeqCst));
}

#[test]
fn malformed_requests_never_touch_the_render() {
    let (p, stop) = start(Mode::Rgb, 3, 3);
    let addr = p.addr();
    let image = test_image(3, 3, false, 1.0);
    p.publish(&report(&image, 1));
    let garbage: Vec<Vec<u8>> = vec![
        b"\x00\x01\x02\xff\xfe garbage\r\n\r\n".to_vec(),
        b"GET\r\n\r\n".to_vec(),
        b"GET /image\r\n\r\n".to_vec(),
        b"GET /image HTTP/9.9\r\n\r\n".to_vec(),
        b"POST /stop HTTP/1.1\r\nContent-Length: -5\r\n\r\n".to_vec(),
        b"POST /stop HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n".to_vec(),
        format!("GET /{} HTTP/1.1\r\n\r\n", "a".repeat(100_000)).into_bytes(),
        format!("GET / HTTP/1.1\r\nX: {}\r\n\r\n", "b".repeat(100_000)).into_bytes(),
        "GET /ünïcode HTTP/1.1\r\n\r\n".as_bytes().to_vec(),
    ];
    for g in &garbage {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let _ = s.write_all(g);
        let _ = s.shutdown(Shutdown::Write);
        let mut sink = vec![];
        let _ = s.read_to_end(&mut sink);
        let status = String::from_utf8_lossy(&sink).split_whitespace().nth(1).and_then(|c| c.parse::<u16>().ok());
        assert!(status.is_none_or(|c| c != 200 && c != 202), "{:?} → {status:?}", String::from_utf8_lossy(&g[..g.len().min(40)]));
    }
    // Connections that send half a request and hang, or nothing at all.
    let idle: Vec<TcpStream> = (0..8)
        .map(|i| {
            let mut s = TcpStream::connect(addr).unwrap();
            if i % 2 == 0 {
                s.write_all(b"GET /image HTTP/1.1\r\nHost: 127.0.0.1\r\n").unwrap();
            }
            s
        })
        .collect();
    // A publish still returns at once, and well-formed requests are
    // answered while those connections stay open.
    let t = Instant::now();
    let next = test_image(3, 3, false, 2.0);
    p.publish(&report(&next, 2));
    assert!(t.elapsed() < Duration::from_millis(500));
    for _ in 0..4 {
        assert_eq!(decode(&get(addr, "/image").body).4, flatten(&next));
        assert_eq!(get(addr, "/progress").status, 200);
    }
    assert!(!stop.load(Ordering::SeqCst), "no malformed request stopped the render");
    drop(idle);
}

#[test]
fn many_clients_at_once_and_a_stalled_one() {
    let (p, _) = start(Mode::Rgb, 64, 48);
    let addr = p.addr();
    let p = Arc::new(p);
    let images: Vec<Image> = (0..6).map(|k| test_image(64, 48, false, 1000.0 * k as f32)).collect();
    let expected: Vec<Vec<f32>> = images.iter().map(flatten).collect();
    p.publish(&report(&images[0], 1));
    // A client that asks for the image and never reads it.
    let mut stalled = TcpStream::connect(addr).unwrap();
    stalled.write_all(format!("GET /image HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n\r\n", addr.port()).as_bytes()).unwrap();

    let done = Arc::new(AtomicBool::new(false));
    let clients: Vec<_> = (0..12)
        .map(|i| {
            let (done, expected) = (done.clone(), expected.clone());
            std::thread::spawn(move || {
                let mut seen = 0;
                while !done.load(Ordering::SeqCst) || seen == 0 {
                    let r = if i % 3 == 0 { get(addr, "/progress") } else { get(addr, "/image") };
                    assert_eq!(r.status, 200);
                    if i % 3 == 0 {
                        assert!(r.json()["pass"].as_u64().unwrap() >= 1);
                    } else {
                        // Every frame is whole and is one of the passes published.
                        let (w, h, _, pass, floats) = decode(&r.body);
                        assert_eq!((w, h), (64, 48));
                        assert_eq!(floats, expected[pass as usize - 1], "pass {pass}");
                    }
                    seen += 1;
                }
                seen
            })
        })
        .collect();
    for (k, image) in images.iter().enumerate().skip(1) {
        std::thread::sleep(Duration::from_millis(30));
        let t = Instant::now();
        p.publish(&report(image, k as u32 + 1));
        assert!(t.elapsed() < Duration::from_millis(500), "publishing never waits on clients");
    }
    done.store(true, Ordering::SeqCst);
    for c in clients {
        assert!(c.join().expect("a client failed") > 0);
    }
    let (_, _, _, pass, _) = decode(&get(addr, "/image").body);
    assert_eq!(pass, 6);
    drop(stalled);
}

/// A real progressive render published pass by pass: the last frame the
/// server holds is the render's image, and the progress reaches the end.
#[test]
fn a_progressive_render_publishes_every_pass() {
    let xml = r#"<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="3"/></integrator>
        <sensor type="perspective">
            <float name="fov" value="40"/>
            <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
            <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="16"/></film>
        </sensor>
        <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        <shape type="sphere"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf></shape>
    </scene>"#;
    let scene = snell::load_str(std::path::Path::new("preview.xml"), xml, &Default::default()).unwrap_or_else(|e| panic!("{e}"));
    let stop = Arc::new(AtomicBool::new(false));
    let p = Preview::start("127.0.0.1:0".parse().unwrap(), Mode::Rgb, 24, 16, stop.clone()).unwrap();
    let passes = snell::preview::default_passes(8);
    assert_eq!(passes, 4);
    let options = RenderOptions { threads: 1, stop: Some(stop), passes, ..RenderOptions::default() };
    let mut seen = vec![];
    let (image, stats) = snell::session::render(&scene, Mode::Rgb, &options, &mut |r| {
        p.publish(r);
        let (_, _, _, pass, floats) = decode(&get(p.addr(), "/image").body);
        assert_eq!(pass, r.pass);
        assert_eq!(floats, flatten(r.image));
        seen.push((r.pass, r.spp_done));
    })
    .unwrap();
    let schedule = snell::render::pass_schedule(8, passes);
    assert_eq!(seen, schedule.iter().enumerate().map(|(k, &spp)| (k as u32 + 1, spp)).collect::<Vec<_>>());
    assert_eq!(seen[0].1, 1, "the preview's passes start at one sample per pixel");
    p.finish(&stats);
    assert_eq!(decode(&get(p.addr(), "/image").body).4, flatten(&image));
    let j = get(p.addr(), "/progress").json();
    assert_eq!((j["state"].as_str(), j["pass"].as_u64(), j["eta_seconds"].as_f64()), (Some("done"), Some(4), Some(0.0)));
}

#[test]
fn a_taken_port_is_a_clear_error() {
    let (p, _) = start(Mode::Rgb, 1, 1);
    let err = Preview::start(p.addr(), Mode::Rgb, 1, 1, Arc::new(AtomicBool::new(false))).err().expect("the port is taken");
    let msg = format!("{err:#}");
    assert!(msg.contains(&p.addr().to_string()) && msg.contains("--preview PORT"), "{msg}");
}

/// The command line: `--preview 0` prints the URL, renders in the default
/// passes (each written by `--preview-dump-passes`, the last equal to the
/// output), and the preview's options need `--preview`.
#[test]
fn the_command_line_serves_and_renders_in_passes() {
    let dir = std::env::temp_dir().join(format!("snell-preview-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("scene.xml");
    std::fs::write(
        &scene,
        r#"<scene version="3.0.0">
        <sensor type="perspective">
            <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
            <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="8"/></film>
        </sensor>
        <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
        <shape type="sphere"><bsdf type="diffuse"/></shape>
    </scene>"#,
    )
    .unwrap();
    let snell = |args: &[&str]| std::process::Command::new(env!("CARGO_BIN_EXE_snell")).args(args).current_dir(&dir).output().unwrap();
    let out = snell(&["render", "scene.xml", "-o", "out.exr", "--preview", "0", "--preview-dump-passes", "passes"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.lines().any(|l| l.starts_with("preview: http://127.0.0.1:") && l.ends_with('/')), "{err}");
    let mut passes: Vec<String> = std::fs::read_dir(dir.join("passes")).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    passes.sort();
    let n = snell::render::pass_schedule(4, snell::preview::default_passes(4)).len();
    assert!(n >= 2, "a preview renders in passes");
    assert_eq!(passes, (1..=n).map(|k| format!("pass-{k:03}.exr")).collect::<Vec<_>>());
    let last = snell::film::output::read_exr(&dir.join(format!("passes/pass-{n:03}.exr"))).unwrap();
    let output = snell::film::output::read_exr(&dir.join("out.exr")).unwrap();
    assert_eq!(last.pixels, output.pixels);

    let out = snell(&["render", "scene.xml", "--preview-bind", "127.0.0.1"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--preview"));
    let _ = std::fs::remove_dir_all(&dir);
}
