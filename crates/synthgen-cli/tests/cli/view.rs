//! `synthgen view`: the server's API over real HTTP, against the binary (a rendered dataset,
//! two datasets, `--results`), the path-escape refusal, and that nothing is written.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use serde_json::Value;

use crate::common::{run, shared_data, stderr, synthgen};

/// A running `synthgen view`, killed when dropped.
pub struct Server {
    child: Child,
    pub url: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Server {
    /// Starts `synthgen view ARGS --port 0` and reads the address it prints.
    pub fn start(args: &[&std::ffi::OsStr]) -> Server {
        let mut child = Command::new(env!("CARGO_BIN_EXE_synthgen"))
            .arg("view")
            .args(args)
            .args(["--port", "0"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("synthgen view starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("address line");
        let url = line.trim().trim_end_matches('/').to_string();
        assert!(url.starts_with("http://127.0.0.1:"), "{line:?}");
        Server { child, url }
    }

    pub fn get(&self, path: &str) -> (u16, Vec<u8>) {
        match ureq::get(&format!("{}{path}", self.url)).call() {
            Ok(r) => {
                let status = r.status();
                let mut body = Vec::new();
                r.into_reader().read_to_end(&mut body).unwrap();
                (status, body)
            }
            Err(ureq::Error::Status(code, r)) => {
                (code, r.into_string().unwrap_or_default().into_bytes())
            }
            Err(e) => panic!("{path}: {e}"),
        }
    }

    pub fn json(&self, path: &str) -> Value {
        let (status, body) = self.get(path);
        assert_eq!(status, 200, "{path}: {}", String::from_utf8_lossy(&body));
        serde_json::from_slice(&body).unwrap()
    }

    /// The status of a request sent byte for byte (no client-side path normalization).
    pub fn raw_status(&self, path: &str) -> u16 {
        self.raw_status_host(path, self.url.trim_start_matches("http://"))
    }

    /// [`Server::raw_status`] with `host` in the `Host` header.
    pub fn raw_status_host(&self, path: &str, host: &str) -> u16 {
        let addr = self.url.trim_start_matches("http://");
        let mut s = TcpStream::connect(addr).unwrap();
        write!(
            s,
            "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut resp = String::new();
        let _ = s.read_to_string(&mut resp);
        resp.split_whitespace()
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0)
    }
}

/// A small BOP dataset: 6 frames of two Linemod-Occluded objects.
pub fn render_small(shared: &Path, out: &Path, seed: &str) {
    let o = run(synthgen()
        .arg("render")
        .arg("--objects")
        .arg(shared.join("lmo/models/obj_000001.ply"))
        .arg(shared.join("lmo/models/obj_000005.ply"))
        .args([
            "--camera", "linemod", "--frames", "6", "--seed", seed, "--split", "test",
        ])
        .arg("--out")
        .arg(out));
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Every file below `dir` with its size and modification time.
fn listing(dir: &Path) -> Vec<(PathBuf, u64, std::time::SystemTime)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let e = e.unwrap();
            let m = e.metadata().unwrap();
            if m.is_dir() {
                stack.push(e.path());
            } else {
                out.push((e.path(), m.len(), m.modified().unwrap()));
            }
        }
    }
    out.sort();
    out
}

fn is_png(b: &[u8]) -> bool {
    b.starts_with(b"\x89PNG")
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn view_serves_frames_images_and_filters_read_only() {
    let shared = shared_data();
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    render_small(&shared, &a, "1");
    render_small(&shared, &b, "2");
    // Estimates: the GT of frame 0 moved 1 cm along x.
    let gt: Value = serde_json::from_str(
        &std::fs::read_to_string(a.join("test/000000/scene_gt.json")).unwrap(),
    )
    .unwrap();
    let mut csv = String::from("scene_id,im_id,obj_id,score,R,t,time\n");
    for g in gt["0"].as_array().unwrap() {
        let r: Vec<String> = g["cam_R_m2c"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.to_string())
            .collect();
        let t: Vec<f64> = g["cam_t_m2c"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        csv += &format!(
            "0,0,{},1.0,{},{} {} {},-1\n",
            g["obj_id"],
            r.join(" "),
            t[0] + 10.0,
            t[1],
            t[2]
        );
    }
    let results = tmp.path().join("results.csv");
    std::fs::write(&results, csv).unwrap();
    let before = listing(&a);

    let s = Server::start(&[
        a.as_os_str(),
        b.as_os_str(),
        "--results".as_ref(),
        results.as_os_str(),
    ]);
    let ds = s.json("/api/datasets");
    assert_eq!(ds["datasets"].as_array().unwrap().len(), 2);
    assert_eq!(ds["datasets"][0]["frames"], 6);
    assert_eq!(ds["datasets"][0]["objects"], serde_json::json!([1, 5]));
    assert_eq!(ds["datasets"][0]["has_results"], true);

    // Paging and filters.
    let p0 = s.json("/api/frames?ds=0&per_page=4");
    assert_eq!(
        (p0["total"].clone(), p0["pages"].clone()),
        (6.into(), 2.into())
    );
    assert_eq!(p0["frames"].as_array().unwrap().len(), 4);
    let p1 = s.json("/api/frames?ds=0&per_page=4&page=1");
    assert_eq!(p1["frames"].as_array().unwrap().len(), 2);
    assert_eq!(p1["frames"][0]["idx"], 4);
    assert_eq!(s.json("/api/frames?ds=0&scene=7")["total"], 0);
    assert_eq!(s.json("/api/frames?ds=0&scene=0&obj=")["total"], 6);
    assert_eq!(s.get("/api/frames?ds=0&obj=abc").0, 400);
    assert_eq!(s.json("/api/frames?ds=0&split=train")["total"], 0);
    assert_eq!(s.json("/api/frames?ds=0&min_visib=1.01")["total"], 0);
    let near = s.json("/api/frames?ds=0&max_dist=0.01");
    assert_eq!(near["total"], 0);
    let obj5 = s.json("/api/frames?ds=0&obj=5");
    for f in obj5["frames"].as_array().unwrap() {
        assert!(f["instances"]
            .as_array()
            .unwrap()
            .iter()
            .any(|i| i["obj_id"] == 5));
    }

    // A frame: poses drawn, the estimate and its errors.
    let f = s.json("/api/frame/0/0");
    assert_eq!(f["has_depth"], true);
    let inst = &f["instances"][0];
    assert_eq!(inst["gt"]["box"].as_array().unwrap().len(), 8);
    assert_eq!(inst["gt"]["axes"].as_array().unwrap().len(), 4);
    let te = inst["estimate"]["te_cm"].as_f64().unwrap();
    assert!((te - 1.0).abs() < 1e-6, "{te}");
    assert!(s.json("/api/frame/0/1")["instances"][0]["estimate"].is_null());
    assert_eq!(s.get("/api/frame/0/6").0, 404);
    assert_eq!(s.get("/api/frame/2/0").0, 404);

    // Images, made on request.
    let (st, rgb) = s.get("/img/0/0/rgb");
    assert!(st == 200 && is_png(&rgb));
    let (st, thumb) = s.get("/img/0/0/thumb");
    assert!(st == 200 && thumb.starts_with(&[0xFF, 0xD8]), "{st}");
    assert_eq!(image::load_from_memory(&thumb).unwrap().width(), 192);
    assert_eq!(s.get("/img/0/0/thumb").1, thumb, "cached thumbnail");
    let (st, depth) = s.get("/img/0/0/depth");
    assert!(st == 200 && is_png(&depth));
    let (_, raw) = s.get("/img/0/0/depth.raw");
    let (w, h) = (
        u32::from_le_bytes(raw[0..4].try_into().unwrap()),
        u32::from_le_bytes(raw[4..8].try_into().unwrap()),
    );
    assert_eq!((w, h), (640, 480));
    assert_eq!(raw.len(), 8 + 2 * 640 * 480);
    for kind in ["masks", "contours"] {
        let (st, m) = s.get(&format!("/img/0/0/{kind}"));
        assert!(st == 200 && is_png(&m), "{kind}");
    }
    assert_eq!(s.get("/img/0/0/nonsense").0, 404);
    assert_eq!(s.get("/img/0/99/rgb").0, 404);

    // Statistics of both datasets on shared bins (what `synthgen stats` computes).
    let st = s.json("/api/stats");
    let list = st["datasets"].as_array().unwrap();
    assert_eq!(list.len(), 2);
    for d in list {
        assert_eq!(d["stats"]["instances"], 12);
        for key in ["distance_m", "elevation_deg", "inplane_deg"] {
            assert!(
                d["stats"][key]["histogram"]["counts"].is_array(),
                "{key}: {d}"
            );
        }
    }
    assert_eq!(
        list[0]["stats"]["distance_m"]["histogram"]["lo"],
        list[1]["stats"]["distance_m"]["histogram"]["lo"]
    );

    // Files of the dataset, and nothing outside it.
    assert_eq!(s.get("/file/0/camera.json").0, 200);
    assert_eq!(s.raw_status("/file/0/../../../../etc/passwd"), 403);
    assert_eq!(s.raw_status("/file/0/%2e%2e/%2e%2e/%2e%2e/etc/passwd"), 403);
    assert_eq!(s.raw_status("/file/0//etc/passwd"), 403);
    let outside = tmp.path().join("secret.txt");
    std::fs::write(&outside, "x").unwrap();
    std::os::unix::fs::symlink(&outside, a.join("link.txt")).unwrap();
    assert_eq!(s.raw_status("/file/0/link.txt"), 403);
    std::fs::remove_file(a.join("link.txt")).unwrap();
    assert_eq!(s.get("/file/0/nothing.png").0, 404);

    // Pages and assets are served from the binary.
    for p in ["/", "/frame", "/stats", "/app.js", "/style.css"] {
        assert_eq!(s.get(p).0, 200, "{p}");
    }
    drop(s);
    assert_eq!(listing(&a), before, "the viewer wrote into the dataset");
}

#[test]
fn view_refuses_a_folder_that_is_not_a_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let o = run(synthgen().arg("view").arg(tmp.path()).args(["--port", "0"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&tmp.path().display().to_string()),
        "{}",
        stderr(&o)
    );
}

/// Issue 26: the viewer answered any `Host` (a page whose name its owner points at this machine,
/// DNS rebinding, could read the datasets) and took `min_visib=nan`.
#[test]
fn view_answers_only_its_own_host_and_refuses_non_finite_filters() {
    let tmp = tempfile::tempdir().unwrap();
    crate::mix::render_tiny(tmp.path(), "a", 2, 1);
    let s = Server::start(&[tmp.path().join("a").as_os_str()]);
    let port = s.url.rsplit(':').next().unwrap().to_string();
    for (host, status) in [
        (format!("127.0.0.1:{port}"), 200),
        (format!("localhost:{port}"), 200),
        (format!("LOCALHOST:{port}"), 200),
        (format!("evil.example:{port}"), 403),
        ("evil.example".to_string(), 403),
        ("127.0.0.1:1".to_string(), 403),
        (format!("10.1.2.3:{port}"), 403),
    ] {
        assert_eq!(
            s.raw_status_host("/api/datasets", &host),
            status,
            "Host: {host}"
        );
    }
    assert_eq!(
        s.raw_status_host("/file/0/camera.json", "evil.example"),
        403
    );
    for q in [
        "min_visib=nan",
        "max_visib=NaN",
        "min_dist=inf",
        "max_dist=-inf",
    ] {
        assert_eq!(s.get(&format!("/api/frames?ds=0&{q}")).0, 400, "{q}");
    }
    assert_eq!(s.get("/api/frames?ds=0&min_visib=0.5").0, 200);
}

#[test]
fn view_on_every_interface_warns_that_anyone_can_read_the_datasets() {
    let tmp = tempfile::tempdir().unwrap();
    crate::mix::render_tiny(tmp.path(), "a", 2, 1);
    let mut child = Command::new(env!("CARGO_BIN_EXE_synthgen"))
        .arg("view")
        .arg(tmp.path().join("a"))
        .args(["--host", "0.0.0.0", "--port", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(line.starts_with("http://0.0.0.0:"), "{line}");
    assert!(
        e.contains("warning:") && e.contains("0.0.0.0") && e.contains("no login"),
        "{e}"
    );
}
