//! `synthgen view` in a real browser: headless Chromium driven over WebDriver (chromedriver,
//! plain HTTP + JSON) opens the grid, clicks a frame, toggles the mask layer and checks the
//! page's state. Ignored (with the reason) where the build script found no Chromium or
//! chromedriver; SYNTHGEN_REQUIRE_CHROMIUM=1 (CI) runs it, and a missing browser fails it. With SYNTHGEN_VIEW_SCREENSHOTS=DIR
//! it saves the grid and the frame page there (docs/view-*.png come from it).

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use serde_json::{json, Value};

use crate::common::shared_data;
use crate::view::{render_small, Server};

fn which(names: &[&str]) -> Option<String> {
    names.iter().find_map(|n| {
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!("command -v {n}"))
            .output()
            .ok()?;
        let p = String::from_utf8_lossy(&o.stdout).trim().to_string();
        (o.status.success() && !p.is_empty()).then_some(p)
    })
}

struct Driver {
    child: Child,
    base: String,
    session: String,
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = ureq::delete(&format!("{}/session/{}", self.base, self.session)).call();
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn post(url: &str, body: Value) -> Value {
    match ureq::post(url).send_json(body) {
        Ok(r) => r.into_json().unwrap(),
        Err(ureq::Error::Status(c, r)) => {
            panic!("{url}: {c} {}", r.into_string().unwrap_or_default())
        }
        Err(e) => panic!("{url}: {e}"),
    }
}

impl Driver {
    fn start(chromedriver: &str, chromium: &str) -> Driver {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new(chromedriver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts");
        let base = format!("http://127.0.0.1:{port}");
        let t0 = Instant::now();
        while ureq::get(&format!("{base}/status")).call().is_err() {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "chromedriver did not come up"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        let caps = json!({"capabilities": {"alwaysMatch": {"goog:chromeOptions": {
            "binary": chromium,
            "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                     "--window-size=1500,1000"]
        }}}});
        let r = post(&format!("{base}/session"), caps);
        let session = r["value"]["sessionId"]
            .as_str()
            .expect("session id")
            .to_string();
        Driver {
            child,
            base,
            session,
        }
    }

    fn url(&self, tail: &str) -> String {
        format!("{}/session/{}{tail}", self.base, self.session)
    }

    fn go(&self, url: &str) {
        post(&self.url("/url"), json!({ "url": url }));
    }

    fn js(&self, script: &str) -> Value {
        post(
            &self.url("/execute/sync"),
            json!({ "script": script, "args": [] }),
        )["value"]
            .clone()
    }

    /// Waits for the page to say it is drawn (`body[data-ready]`) or failed.
    fn wait_ready(&self) {
        let t0 = Instant::now();
        loop {
            let v = self.js("return [document.body && document.body.dataset.ready, document.body && document.body.dataset.error]");
            assert!(v[1].is_null(), "page error: {}", v[1]);
            if v[0] == "1" {
                return;
            }
            assert!(t0.elapsed() < Duration::from_secs(20), "page not ready");
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    fn click(&self, css: &str) {
        let e = post(
            &self.url("/element"),
            json!({"using": "css selector", "value": css}),
        );
        let id = e["value"]
            .as_object()
            .and_then(|o| o.values().next())
            .and_then(Value::as_str)
            .expect("element")
            .to_string();
        post(&self.url(&format!("/element/{id}/click")), json!({}));
    }

    fn screenshot(&self, name: &str) {
        let Ok(dir) = std::env::var("SYNTHGEN_VIEW_SCREENSHOTS") else {
            return;
        };
        let v: Value = ureq::get(&self.url("/screenshot"))
            .call()
            .unwrap()
            .into_json()
            .unwrap();
        let png = base64::engine::general_purpose::STANDARD
            .decode(v["value"].as_str().unwrap())
            .unwrap();
        std::fs::write(std::path::Path::new(&dir).join(name), png).unwrap();
    }
}

#[test]
#[cfg_attr(
    not(has_chromium),
    ignore = "needs chromium and chromedriver: apt-get install chromium chromium-driver (probed when the crate was built)"
)]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn view_in_headless_chromium_grid_frame_and_mask_toggle() {
    let (Some(driver), Some(chromium)) = (
        which(&["chromedriver"]),
        which(&["chromium", "chromium-browser", "google-chrome"]),
    ) else {
        panic!("chromium or chromedriver is missing (they were there when the tests were built, or SYNTHGEN_REQUIRE_CHROMIUM=1)");
    };
    let shared = shared_data();
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (
        tmp.path().join("lmo_synth_a"),
        tmp.path().join("lmo_synth_b"),
    );
    render_small(&shared, &a, "1");
    render_small(&shared, &b, "2");
    let s = Server::start(&[a.as_os_str(), b.as_os_str()]);
    let d = Driver::start(&driver, &chromium);

    // Two datasets: side by side, six thumbnails each.
    d.go(&format!("{}/", s.url));
    d.wait_ready();
    assert_eq!(
        d.js("return document.querySelectorAll('.column').length"),
        2
    );
    assert_eq!(
        d.js("return document.querySelectorAll('.thumb').length"),
        12
    );
    // One of them: its six thumbnails, loaded.
    d.go(&format!("{}/?ds=0", s.url));
    d.wait_ready();
    assert_eq!(d.js("return document.querySelectorAll('.thumb').length"), 6);
    let t0 = Instant::now();
    while d.js("return [...document.querySelectorAll('.thumb img')].every(i => i.complete && i.naturalWidth > 0)") != true {
        assert!(t0.elapsed() < Duration::from_secs(20), "thumbnails did not load");
        std::thread::sleep(Duration::from_millis(100));
    }
    d.screenshot("view-grid.png");
    assert_eq!(
        d.js("return document.querySelectorAll('.column').length"),
        1
    );

    // Click the third frame: its page, with the masks hidden at first.
    d.click(".thumb:nth-child(3)");
    d.wait_ready();
    let url = d.js("return location.pathname + location.search");
    assert_eq!(url, "/frame?ds=0&idx=2");
    assert_eq!(
        d.js("return document.getElementById('img-masks').classList.contains('hidden')"),
        true
    );
    assert!(
        d.js("return document.querySelectorAll('#objects tbody tr').length")
            .as_u64()
            .unwrap()
            >= 1
    );
    // Toggle the mask layer on: shown, and its image loaded.
    d.click("#layer-masks");
    assert_eq!(
        d.js("return document.getElementById('img-masks').classList.contains('hidden')"),
        false
    );
    let t0 = Instant::now();
    while d
        .js("const i = document.getElementById('img-masks'); return i.complete && i.naturalWidth")
        != 640
    {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "mask layer did not load"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    // The boxes are drawn on the overlay canvas (some pixel is not transparent).
    let drawn = d.js("const c = document.getElementById('overlay'); const px = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; for (let i = 3; i < px.length; i += 4) if (px[i]) return true; return false;");
    assert_eq!(drawn, true);
    // Toggling it off again hides it.
    d.click("#layer-masks");
    assert_eq!(
        d.js("return document.getElementById('img-masks').classList.contains('hidden')"),
        true
    );
    d.click("#layer-masks");
    d.screenshot("view-frame.png");

    // The statistics page draws both datasets.
    d.go(&format!("{}/stats", s.url));
    d.wait_ready();
    // Visible fraction, distance, elevation, in-plane rotation.
    assert_eq!(
        d.js("return document.querySelectorAll('svg.chart').length"),
        4
    );
    d.screenshot("view-stats.png");
}
