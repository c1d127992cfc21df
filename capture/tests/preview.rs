//! The live preview page in headless Chromium (Debian `chromium`, installed by
//! `scripts/install-system-deps.sh`): it loads, fetches the latest view and draws its pictures
//! and histogram.

use rmvp_capture::preview::{serve, Preview};
use rmvp_capture::sensor::SensorModel;
use rmvp_capture::FrameProcessor;
use rmvp_dataset::io::png::{read_png, PngImage};
use rmvp_dataset::{Image, Stokes};
use std::io::{Read, Write};
use std::sync::Arc;

/// A 256x192 Stokes image: a bright disc whose AoP turns with the polar angle, fully polarized.
fn disc() -> Stokes {
    let (w, h) = (256, 192);
    let mut s = [Image::new(w, h, 3), Image::new(w, h, 3), Image::new(w, h, 3)];
    for y in 0..h {
        for x in 0..w {
            let (dx, dy) = (x as f32 - 128.0, y as f32 - 96.0);
            if dx * dx + dy * dy > 80.0 * 80.0 {
                continue;
            }
            let phi = dy.atan2(dx);
            for c in 0..3 {
                let k = (y * w + x) * 3 + c;
                s[0].data_mut()[k] = 0.8;
                s[1].data_mut()[k] = 0.6 * (2.0 * phi).cos();
                s[2].data_mut()[k] = 0.6 * (2.0 * phi).sin();
            }
        }
    }
    let [s0, s1, s2] = s;
    Stokes { s0, s1, s2 }
}

fn http_get(address: std::net::SocketAddr, path: &str) -> String {
    let mut stream = std::net::TcpStream::connect(address).unwrap();
    write!(stream, "GET {path} HTTP/1.1\r\nHost: preview\r\nConnection: close\r\n\r\n").unwrap();
    let mut response = Vec::new();
    stream.read_to_end(&mut response).unwrap();
    String::from_utf8_lossy(&response).into_owned()
}

#[test]
fn the_preview_page_shows_the_latest_view_in_chromium() {
    let preview = Arc::new(Preview::default());
    let server = serve(preview.clone(), "127.0.0.1:0".parse().unwrap()).unwrap();
    assert!(http_get(server.address, "/state.json").contains("\"version\":0"));

    let raw = SensorModel::default().noise_free().expose(&disc(), 0, 0);
    let frame = FrameProcessor::default().process(&raw).unwrap();
    preview.update(&frame, "007", 8, 60);
    let state = http_get(server.address, "/state.json");
    assert!(state.contains("\"version\":1") && state.contains("\"view\":\"007\""), "{state}");
    assert!(http_get(server.address, "/aop.png").contains("image/png"));

    let tmp = tempfile::tempdir().unwrap();
    let shot = tmp.path().join("preview.png");
    let chromium = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| std::process::Command::new(c).arg("--version").output().is_ok_and(|o| o.status.success()))
        .expect("Chromium is needed for this test: run scripts/install-system-deps.sh test");
    let out = std::process::Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--window-size=1700,700",
            "--virtual-time-budget=4000",
        ])
        .arg(format!("--user-data-dir={}", tmp.path().join("profile").display()))
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("http://{}/", server.address))
        .output()
        .unwrap();
    assert!(shot.exists(), "no screenshot: {}", String::from_utf8_lossy(&out.stderr));
    let PngImage::U8(picture) = read_png(&shot).unwrap() else { panic!("8-bit screenshot") };
    let c = picture.channels();
    let pixels: Vec<&[u8]> = picture.data().chunks_exact(c).collect();
    // The AoP picture: a full hue wheel, so strongly coloured pixels of every hue sector.
    let mut sectors = [0usize; 6];
    for p in &pixels {
        let (r, g, b) = (p[0] as i32, p[1] as i32, p[2] as i32);
        let (max, min) = (r.max(g).max(b), r.min(g).min(b));
        if max > 120 && max - min > 100 {
            let sector = if max == r {
                if g >= b {
                    0
                } else {
                    5
                }
            } else if max == g {
                if b >= r {
                    2
                } else {
                    1
                }
            } else if r >= g {
                4
            } else {
                3
            };
            sectors[sector] += 1;
        }
    }
    assert!(sectors.iter().all(|&n| n > 200), "AoP hues in the screenshot: {sectors:?}");
    // The histogram's bars (#8cf) are drawn.
    let bars = pixels.iter().filter(|p| p[0] == 0x88 && p[1] == 0xcc && p[2] == 0xff).count();
    assert!(bars > 500, "{bars} histogram pixels");
    // The status line was filled in by the page's script, so the fetch worked: the grey
    // "waiting" state has no pictures at all, which the checks above exclude.
}
