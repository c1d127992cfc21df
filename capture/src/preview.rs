//! Live preview of a capture session: a small local web page (tokio + axum) with the latest
//! view's S0, AoP and DoP pictures and the histogram of its polarizer-angle intensities (the
//! right-most bin is saturation), refreshed as views arrive.

use crate::pipeline::ProcessedFrame;
use crate::session::hdr::SATURATION_FRACTION;
use crate::{Error, Result};
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use rmvp_dataset::io::png::encode_png_u8;
use rmvp_dataset::visualize;
use serde::Serialize;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

/// Histogram bins of the angle intensities (fraction of full scale).
pub const HISTOGRAM_BINS: usize = 64;
/// Widest picture served (pixels); larger views are shrunk by whole factors.
const PREVIEW_WIDTH: usize = 640;

/// What the page shows.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PreviewState {
    /// Increases with every update (the page reloads pictures when it changes).
    pub version: u64,
    /// Name of the view shown.
    pub view: String,
    /// Views complete.
    pub done: usize,
    /// Views planned.
    pub planned: usize,
    /// Counts of angle intensities in [`HISTOGRAM_BINS`] equal bins of full scale.
    pub histogram: Vec<u64>,
    /// Fraction of angle samples at or above the saturation level.
    pub saturated_fraction: f64,
    #[serde(skip)]
    pictures: [Vec<u8>; 3],
}

/// The latest view, shared by the session (writer) and the web server.
#[derive(Default)]
pub struct Preview {
    state: Mutex<PreviewState>,
}

impl Preview {
    /// Show `frame` (view `name`, `done` of `planned`).
    pub fn update(&self, frame: &ProcessedFrame, name: &str, done: usize, planned: usize) {
        let stokes = &frame.estimate.stokes;
        let pictures = [
            visualize::preview(&stokes.s0),
            visualize::aop_picture(&frame.aop, &frame.dop, None),
            visualize::gray_ramp(&frame.dop, 0.0, 1.0),
        ]
        .map(|p| encode_png_u8(&visualize::downsample(&p, p.width().div_ceil(PREVIEW_WIDTH))).unwrap_or_default());
        let full = ((1u32 << frame.bits) - 1) as f64;
        let mut histogram = vec![0u64; HISTOGRAM_BINS];
        let mut saturated = 0u64;
        let mut total = 0u64;
        for angle in &frame.angles {
            for &v in angle.data() {
                let x = v as f64 / full;
                histogram[((x * HISTOGRAM_BINS as f64) as usize).min(HISTOGRAM_BINS - 1)] += 1;
                saturated += u64::from(x >= SATURATION_FRACTION);
                total += 1;
            }
        }
        let mut state = self.state.lock().expect("preview state");
        *state = PreviewState {
            version: state.version + 1,
            view: name.to_string(),
            done,
            planned,
            histogram,
            saturated_fraction: saturated as f64 / total.max(1) as f64,
            pictures,
        };
    }

    /// A copy of what the page shows now.
    pub fn state(&self) -> PreviewState {
        self.state.lock().expect("preview state").clone()
    }
}

/// A running preview server; it stops when dropped.
pub struct PreviewServer {
    /// Address it listens on.
    pub address: SocketAddr,
    shutdown: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for PreviewServer {
    fn drop(&mut self) {
        if let Some(stop) = self.shutdown.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Serve `preview` on `address` (e.g. `127.0.0.1:8642`; port 0 picks a free one) from a
/// background thread.
pub fn serve(preview: Arc<Preview>, address: SocketAddr) -> Result<PreviewServer> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_io()
        .build()
        .map_err(|e| Error::Unsupported(format!("preview server: {e}")))?;
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind(address))
        .map_err(|e| Error::Unsupported(format!("preview server: cannot listen on {address}: {e}")))?;
    let address = listener.local_addr().map_err(|e| Error::Unsupported(format!("preview server: {e}")))?;
    let app = axum::Router::new()
        .route("/", get(|| async { Html(PAGE) }))
        .route("/state.json", get(state_json))
        .route("/{picture}", get(picture))
        .with_state(preview);
    let (shutdown, stopped) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::Builder::new()
        .name("preview server".into())
        .spawn(move || {
            runtime.block_on(async move {
                let _ = axum::serve(listener, app)
                    .with_graceful_shutdown(async move {
                        let _ = stopped.await;
                    })
                    .await;
            });
        })
        .map_err(|e| Error::Unsupported(format!("preview server: {e}")))?;
    Ok(PreviewServer { address, shutdown: Some(shutdown), thread: Some(thread) })
}

async fn state_json(State(preview): State<Arc<Preview>>) -> axum::Json<PreviewState> {
    axum::Json(preview.state())
}

async fn picture(State(preview): State<Arc<Preview>>, Path(name): Path<String>) -> Response {
    let index = match name.as_str() {
        "s0.png" => 0,
        "aop.png" => 1,
        "dop.png" => 2,
        _ => return StatusCode::NOT_FOUND.into_response(),
    };
    let bytes = preview.state.lock().expect("preview state").pictures[index].clone();
    if bytes.is_empty() {
        return StatusCode::NO_CONTENT.into_response();
    }
    ([(header::CONTENT_TYPE, "image/png"), (header::CACHE_CONTROL, "no-store")], bytes).into_response()
}

/// The page: pictures reloaded and the histogram redrawn whenever `version` changes.
const PAGE: &str = r#"<!doctype html>
<html><head><meta charset="utf-8"><title>rmvp capture preview</title>
<style>
body { font-family: sans-serif; background: #222; color: #eee; margin: 16px; }
.row { display: flex; gap: 12px; flex-wrap: wrap; }
figure { margin: 0; } figcaption { font-size: 14px; margin: 4px 0; }
img, canvas { width: 400px; background: #000; display: block; }
</style></head>
<body>
<h2>rmvp capture: <span id="status">waiting for the first view</span></h2>
<div class="row">
<figure><figcaption>S0</figcaption><img id="s0" alt="S0"></figure>
<figure><figcaption>AoP (hue) weighted by DoP</figcaption><img id="aop" alt="AoP"></figure>
<figure><figcaption>DoP (0 to 1)</figcaption><img id="dop" alt="DoP"></figure>
<figure><figcaption>Angle intensities (right: saturated)</figcaption><canvas id="hist" width="400" height="200"></canvas></figure>
</div>
<script>
let shown = -1;
function draw(h) {
  const c = document.getElementById('hist'), g = c.getContext('2d');
  g.fillStyle = '#000'; g.fillRect(0, 0, c.width, c.height);
  const logs = h.map(v => Math.log10(1 + v)), top = Math.max(...logs, 1), w = c.width / h.length;
  logs.forEach((v, i) => {
    g.fillStyle = i >= h.length * 0.95 ? '#f44' : '#8cf';
    const bar = v / top * (c.height - 4);
    g.fillRect(i * w, c.height - bar, w - 1, bar);
  });
}
async function poll() {
  try {
    const s = await (await fetch('state.json', {cache: 'no-store'})).json();
    if (s.version !== shown && s.version > 0) {
      shown = s.version;
      for (const k of ['s0', 'aop', 'dop']) document.getElementById(k).src = k + '.png?v=' + s.version;
      document.getElementById('status').textContent =
        `view ${s.view}, ${s.done} of ${s.planned} done, ${(100 * s.saturated_fraction).toFixed(2)} % saturated`;
      draw(s.histogram);
    }
  } catch (e) { document.getElementById('status').textContent = 'capture not running'; }
  setTimeout(poll, 500);
}
poll();
</script>
</body></html>
"#;
