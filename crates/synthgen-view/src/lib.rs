//! `synthgen view`: a local dataset browser. A small HTTP server (axum on tokio) over the
//! datasets given to it, read-only, serving a front end of plain HTML, CSS and JavaScript
//! compiled into the binary (no bundler, no CDN). Pages: the frame grid with paging and
//! filters, a frame with its layers (RGB, depth, masks, contours, 3D boxes, axes; the
//! estimates of `--results` beside the GT), and the statistics. See docs/view.md.
//!
//! Only annotations are read up front; images are read, decoded and drawn when a page asks
//! for them (thumbnails are cached in memory). No request can reach a file outside the
//! datasets: images are addressed by (dataset, frame), and `/file/…` paths are resolved and
//! checked to lie below the dataset's root. Requests must name this server in `Host` (its
//! address, or `localhost` on loopback): a web page whose own name resolves here (DNS
//! rebinding) sends its name and is refused.

mod images;
mod state;

use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::sync::Arc;

use axum::extract::{Path as UrlPath, Query, State};
use axum::http::{header, StatusCode};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use serde_json::{json, Value};
use synthgen_core::glam::DVec3;
use synthgen_core::{Intrinsics, Pose};
use synthgen_curate::preview::{box_corners, EDGES};

pub use state::{Dataset, Filter, FrameSummary, Viewer};

/// What can go wrong opening datasets or answering a request.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot open {path}: {message}")]
    Open { path: PathBuf, message: String },
    #[error("cannot read {path}: {message}")]
    Image { path: PathBuf, message: String },
    #[error("not found: {0}")]
    NotFound(&'static str),
    #[error("refused: {0}")]
    Forbidden(String),
    #[error("bad request: {0}")]
    BadRequest(String),
}

impl IntoResponse for Error {
    fn into_response(self) -> Response {
        let status = match self {
            Error::NotFound(_) => StatusCode::NOT_FOUND,
            Error::Forbidden(_) => StatusCode::FORBIDDEN,
            Error::BadRequest(_) => StatusCode::BAD_REQUEST,
            _ => StatusCode::INTERNAL_SERVER_ERROR,
        };
        (status, self.to_string()).into_response()
    }
}

type Shared = Arc<Viewer>;

const INDEX_HTML: &str = include_str!("assets/index.html");
const FRAME_HTML: &str = include_str!("assets/frame.html");
const STATS_HTML: &str = include_str!("assets/stats.html");
const APP_JS: &str = include_str!("assets/app.js");
const STYLE_CSS: &str = include_str!("assets/style.css");

/// Which `Host` values a server bound to `bound` answers: its own address; any IP address
/// when bound to all interfaces (which of them a client used is unknown); `localhost` on
/// loopback or all interfaces. Always with the bound port. Names other than `localhost` are
/// refused: a page served from `evil.example`, whose name its owner pointed at this machine
/// (DNS rebinding), sends `Host: evil.example`.
#[derive(Debug, Clone, Copy)]
pub struct HostGuard {
    pub bound: SocketAddr,
}

impl HostGuard {
    pub fn allows(&self, host: &str) -> bool {
        let (name, port) = match host.strip_prefix('[') {
            Some(rest) => match rest.split_once(']') {
                Some((ip, tail)) => (ip, tail.strip_prefix(':')),
                None => return false,
            },
            None => match host.rsplit_once(':') {
                Some((n, p)) => (n, Some(p)),
                None => (host, None),
            },
        };
        let port_ok = match port {
            Some(p) => p.parse::<u16>() == Ok(self.bound.port()),
            None => self.bound.port() == 80,
        };
        let ip = self.bound.ip();
        port_ok
            && match name.parse::<IpAddr>() {
                Ok(a) => a == ip || ip.is_unspecified() || (ip.is_loopback() && a.is_loopback()),
                Err(_) => {
                    name.eq_ignore_ascii_case("localhost")
                        && (ip.is_loopback() || ip.is_unspecified())
                }
            }
    }
}

async fn check_host(
    State(guard): State<HostGuard>,
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    let host = req
        .uri()
        .authority()
        .map(|a| a.as_str().to_owned())
        .or_else(|| {
            req.headers()
                .get(header::HOST)
                .and_then(|h| h.to_str().ok())
                .map(str::to_owned)
        });
    match host {
        Some(h) if guard.allows(&h) => next.run(req).await,
        h => Error::Forbidden(format!(
            "Host {:?} is not this server ({}): open it by its address",
            h.unwrap_or_default(),
            guard.bound
        ))
        .into_response(),
    }
}

/// The routes: pages, `/api/…` (JSON), `/img/…` (images by dataset and frame), `/file/…`;
/// requests whose `Host` is not the server bound at `bound` are refused ([`HostGuard`]).
pub fn router(viewer: Shared, bound: SocketAddr) -> Router {
    Router::new()
        .route("/", get(|| async { Html(INDEX_HTML) }))
        .route("/frame", get(|| async { Html(FRAME_HTML) }))
        .route("/stats", get(|| async { Html(STATS_HTML) }))
        .route(
            "/app.js",
            get(|| async { ([(header::CONTENT_TYPE, "text/javascript")], APP_JS) }),
        )
        .route(
            "/style.css",
            get(|| async { ([(header::CONTENT_TYPE, "text/css")], STYLE_CSS) }),
        )
        .route("/api/datasets", get(datasets))
        .route("/api/frames", get(frames))
        .route("/api/frame/{ds}/{idx}", get(frame))
        .route("/api/stats", get(stats))
        .route("/img/{ds}/{idx}/{kind}", get(image))
        .route("/file/{ds}/{*path}", get(file))
        .with_state(viewer)
        .layer(axum::middleware::from_fn_with_state(
            HostGuard { bound },
            check_host,
        ))
}

async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, Error> + Send + 'static,
) -> Result<T, Error> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| Error::Forbidden(format!("internal: {e}")))?
}

async fn datasets(State(v): State<Shared>) -> Json<Value> {
    let list: Vec<Value> = v
        .datasets
        .iter()
        .enumerate()
        .map(|(id, d)| {
            let mut splits: Vec<&str> = d.summaries.iter().map(|s| s.split.as_str()).collect();
            splits.dedup();
            splits.sort_unstable();
            splits.dedup();
            let mut scenes: Vec<u32> = d.summaries.iter().map(|s| s.scene_id).collect();
            scenes.sort_unstable();
            scenes.dedup();
            let mut objects: Vec<u32> = d
                .summaries
                .iter()
                .flat_map(|s| s.instances.iter().map(|i| i.obj_id))
                .collect();
            objects.sort_unstable();
            objects.dedup();
            json!({
                "id": id, "name": d.name, "root": d.root, "frames": d.frames.len(),
                "splits": splits, "scenes": scenes, "objects": objects,
                "has_results": !d.estimates.is_empty(),
            })
        })
        .collect();
    Json(json!({ "datasets": list, "results": v.results }))
}

/// `/api/frames`'s query, as the grid's form sends it (empty fields mean "any").
type FramesQuery = std::collections::HashMap<String, String>;

/// A number field of the query: finite (`nan` and `inf` are 400s, as docs/view.md says).
fn number_field(q: &FramesQuery, key: &str) -> Result<Option<f64>, Error> {
    match field::<f64>(q, key)? {
        Some(v) if !v.is_finite() => Err(Error::BadRequest(format!(
            "{key}={v} is not a finite number"
        ))),
        v => Ok(v),
    }
}

/// Field `key` of the query parsed, None when absent or empty.
fn field<T: std::str::FromStr>(q: &FramesQuery, key: &str) -> Result<Option<T>, Error> {
    match q.get(key).map(|v| v.trim()).filter(|v| !v.is_empty()) {
        None => Ok(None),
        Some(v) => v
            .parse()
            .map(Some)
            .map_err(|_| Error::BadRequest(format!("{key}={v:?} is not a valid value"))),
    }
}

async fn frames(
    State(v): State<Shared>,
    Query(q): Query<FramesQuery>,
) -> Result<Json<Value>, Error> {
    let ds: usize = field(&q, "ds")?.unwrap_or(0);
    let page_no: usize = field(&q, "page")?.unwrap_or(0);
    let per_page = field::<usize>(&q, "per_page")?.unwrap_or(60).clamp(1, 500);
    let filter = Filter {
        obj: field(&q, "obj")?,
        scene: field(&q, "scene")?,
        split: field(&q, "split")?,
        min_visib: number_field(&q, "min_visib")?,
        max_visib: number_field(&q, "max_visib")?,
        min_dist: number_field(&q, "min_dist")?,
        max_dist: number_field(&q, "max_dist")?,
    };
    let d = v
        .datasets
        .get(ds)
        .ok_or(Error::NotFound("no such dataset"))?;
    let mut total = 0usize;
    let mut page = Vec::new();
    for s in d.summaries.iter().filter(|s| filter.keeps(s)) {
        if total >= page_no * per_page && page.len() < per_page {
            page.push(s);
        }
        total += 1;
    }
    Ok(Json(json!({
        "ds": ds, "total": total, "page": page_no, "per_page": per_page,
        "pages": total.div_ceil(per_page), "frames": page,
    })))
}

fn project(k: &Intrinsics, p: DVec3) -> Value {
    if p.z <= 1e-3 {
        return Value::Null;
    }
    json!([k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy])
}

/// A pose drawn: its box corners and its axes (origin, x, y, z ends), projected.
fn drawn(k: &Intrinsics, d: &Dataset, obj_id: u32, pose: &Pose) -> Value {
    let Some(info) = d.models.get(&obj_id) else {
        return json!({ "origin": project(k, pose.translation_m) });
    };
    let corners: Vec<Value> = box_corners(info)
        .iter()
        .map(|&c| project(k, pose.transform_point(c)))
        .collect();
    let half = info.diameter / 2000.0;
    let axes: Vec<Value> = [
        DVec3::ZERO,
        DVec3::X * half,
        DVec3::Y * half,
        DVec3::Z * half,
    ]
    .iter()
    .map(|&a| project(k, pose.transform_point(a)))
    .collect();
    json!({ "box": corners, "axes": axes, "origin": project(k, pose.translation_m) })
}

async fn frame(
    State(v): State<Shared>,
    UrlPath((ds, idx)): UrlPath<(usize, usize)>,
) -> Result<Json<Value>, Error> {
    let (d, f) = v.frame(ds, idx).ok_or(Error::NotFound("no such frame"))?;
    let cam = d.source.camera();
    let k = f.camera.intrinsics(cam.width, cam.height);
    let instances: Vec<Value> =
        f.gt.iter()
            .enumerate()
            .map(|(g, e)| {
                let pose = e.cam_from_obj();
                let info = f.gt_info.as_ref().and_then(|i| i.get(g));
                let est = d.estimates.get(&(idx, g)).map(|(est, err)| {
                    let mut j = drawn(&k, d, e.obj_id, &est.pose);
                    j["score"] = json!(est.score);
                    j["add_s_mm"] = json!(err.add_s_m * 1000.0);
                    j["te_cm"] = json!(err.te_m * 100.0);
                    j["re_deg"] = json!(err.re_deg);
                    j
                });
                json!({
                    "gt_id": g, "obj_id": e.obj_id,
                    "distance_m": pose.translation_m.length(),
                    "visib_fract": info.map(|i| i.visib_fract),
                    "px_count_visib": info.map(|i| i.px_count_visib),
                    "bbox_visib": info.map(|i| i.bbox_visib),
                    "gt": drawn(&k, d, e.obj_id, &pose),
                    "estimate": est,
                })
            })
            .collect();
    Ok(Json(json!({
        "ds": ds, "idx": idx, "frames": d.frames.len(),
        "split": f.location.split, "scene_id": f.location.scene_id, "im_id": f.location.im_id,
        "width": cam.width, "height": cam.height, "cam_K": f.camera.cam_k,
        "depth_scale": f.camera.depth_scale, "has_depth": f.depth.is_some(),
        "has_masks": f.masks_visib.iter().any(Option::is_some),
        "edges": EDGES, "instances": instances,
    })))
}

/// `synthgen stats` of every dataset on shared bins (visible fraction, distance, elevation,
/// in-plane rotation, instances per object), computed on first request and kept.
async fn stats(State(v): State<Shared>) -> Result<Json<Value>, Error> {
    let viewer = v.clone();
    blocking(move || {
        let value = viewer.stats.get_or_init(|| {
            let sources: Vec<&dyn synthgen_formats::source::FrameSource> =
                viewer.datasets.iter().map(|d| d.source.as_ref()).collect();
            synthgen_curate::stats::compare_stats(&sources)
                .map(|all| {
                    let list: Vec<Value> = all
                        .iter()
                        .zip(&viewer.datasets)
                        .map(|(s, d)| json!({ "name": d.name, "stats": s }))
                        .collect();
                    json!({ "datasets": list })
                })
                .map_err(|e| e.to_string())
        });
        match value {
            Ok(v) => Ok(Json(v.clone())),
            Err(e) => Err(Error::Image {
                path: viewer.datasets[0].root.clone(),
                message: e.clone(),
            }),
        }
    })
    .await
}

async fn image(
    State(v): State<Shared>,
    UrlPath((ds, idx, kind)): UrlPath<(usize, usize, String)>,
) -> Result<Response, Error> {
    let viewer = v.clone();
    blocking(move || {
        let (_, f) = viewer
            .frame(ds, idx)
            .ok_or(Error::NotFound("no such frame"))?;
        let (bytes, kind): (Vec<u8>, &'static str) = match kind.as_str() {
            "rgb" => images::file_bytes(&f.rgb)?,
            "thumb" => {
                let b = match viewer.thumbs.get((ds, idx)) {
                    Some(b) => b,
                    None => {
                        let b = Arc::new(images::thumbnail(f)?);
                        viewer.thumbs.put((ds, idx), b.clone());
                        b
                    }
                };
                ((*b).clone(), "image/jpeg")
            }
            "depth" => (images::depth_colour(f)?, "image/png"),
            "depth.raw" => (images::depth_raw(f)?, "application/octet-stream"),
            "masks" => (images::mask_overlay(f, false)?, "image/png"),
            "contours" => (images::mask_overlay(f, true)?, "image/png"),
            _ => return Err(Error::NotFound("no such image kind")),
        };
        Ok(([(header::CONTENT_TYPE, kind)], bytes).into_response())
    })
    .await
}

/// A file of a dataset by its path below the root; anything resolving outside is refused.
async fn file(
    State(v): State<Shared>,
    UrlPath((ds, path)): UrlPath<(usize, String)>,
) -> Result<Response, Error> {
    let d = v
        .datasets
        .get(ds)
        .ok_or(Error::NotFound("no such dataset"))?;
    let root = d.root.clone();
    blocking(move || {
        let wanted = root.join(&path);
        let real = wanted
            .canonicalize()
            .map_err(|_| Error::NotFound("no such file"))?;
        if !real.starts_with(&root) || !real.is_file() {
            return Err(Error::Forbidden(format!("{path} is outside the dataset")));
        }
        let bytes = std::fs::read(&real).map_err(|e| Error::Image {
            path: real.clone(),
            message: e.to_string(),
        })?;
        let kind = match real.extension().and_then(|e| e.to_str()) {
            Some("png") => "image/png",
            Some("jpg" | "jpeg") => "image/jpeg",
            Some("json") => "application/json",
            _ => "application/octet-stream",
        };
        Ok(([(header::CONTENT_TYPE, kind)], bytes).into_response())
    })
    .await
}

/// Serves `viewer` on `addr` until the process ends; `ready` gets the bound address (port 0
/// picks a free one). Blocks.
pub fn serve(
    viewer: Viewer,
    addr: SocketAddr,
    ready: impl FnOnce(SocketAddr) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::bind(addr).await?;
        let bound = listener.local_addr()?;
        ready(bound)?;
        axum::serve(listener, router(Arc::new(viewer), bound)).await
    })
}
