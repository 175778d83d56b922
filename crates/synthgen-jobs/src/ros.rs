//! `synthgen ros`: the [`Predictor`] of `synthgen predict` as a ROS 2 node. It subscribes a
//! colour `sensor_msgs/Image`, its `CameraInfo` and, for the RGB-D models, the registered depth
//! image; per colour image it runs the detector and the pose model and publishes
//! `vision_msgs/Detection3DArray` (a pose per object, in the image's `frame_id` and stamp) and
//! `Detection2DArray` (the boxes), an empty array when nothing was found. Frames that arrive
//! while one is being processed are replaced by the newest (a robot wants the latest pose, not
//! a queue); bad input (an unknown encoding, no camera info yet, an image whose size is not its
//! camera info's, depth missing or of another size) is logged, counted and skipped, and the node
//! keeps running. The DDS side is synthgen-ros' [`PoseNode`].

use std::collections::{BTreeMap, VecDeque};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::Result;
use serde::Serialize;
use synthgen_core::Progress;
use synthgen_formats::bop::{Plane, RgbImage};
use synthgen_formats::output::check_apart;
use synthgen_ros::msgs::{
    quaternion_from_matrix, BoundingBox2D, BoundingBox3D, CameraInfo, Covariance, Detection2D,
    Detection2DArray, Detection3D, Detection3DArray, Image, ObjectHypothesis,
    ObjectHypothesisWithPose, Point, Point2D, Pose, Pose2D, PoseWithCovariance, Quaternion,
};
pub use synthgen_ros::node::NodeConfig;
use synthgen_ros::node::PoseNode;
use synthgen_ros::record::Recorder;
use synthgen_ros::rosbag::{decode_pixels, nearest_in_stamp, Decoded, DEPTH_PAIRING_S};

use crate::predict::{FoundObject, Predictor, PredictorOptions};
use crate::{user_error, Log};

/// The summary's latency percentiles cover at most this many frames (the first ones).
pub const LATENCIES_KEPT: usize = 100_000;

/// A colour image waits this long for its depth before it is skipped.
pub const DEPTH_WAIT: Duration = Duration::from_millis(200);

/// What `synthgen ros` runs.
#[derive(Debug, Clone)]
pub struct RosRequest {
    /// The models (its `objects_from` is unused: the pose model's training dataset).
    pub predictor: PredictorOptions,
    pub node: NodeConfig,
    /// Record what was published into this MCAP file.
    pub record: Option<PathBuf>,
    /// Replace an existing `record` file.
    pub force: bool,
    /// Stop after this many frames processed.
    pub max_frames: Option<usize>,
    /// Stop after this many seconds.
    pub duration: Option<f64>,
    /// A status line (frames, rate, latency, memory) every this many seconds.
    pub status_every: f64,
    pub jobs: Option<usize>,
}

/// What a node run did.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RosSummary {
    /// Frames processed and published.
    pub frames: usize,
    /// Objects published with a pose (Detection3DArray entries).
    pub poses: usize,
    /// Colour images replaced by a newer one before they were processed.
    pub replaced: usize,
    /// Messages skipped, per reason.
    pub skipped: BTreeMap<String, usize>,
    /// Seconds from a colour image's arrival to its detections' publication, over the first
    /// [`LATENCIES_KEPT`] frames.
    pub latency_median_s: f64,
    pub latency_p95_s: f64,
    /// Resident memory after the first frame and at the end, MiB.
    pub rss_first_mib: f64,
    pub rss_end_mib: f64,
    /// Seconds the node ran.
    pub seconds: f64,
}

/// Resident memory of this process, MiB (Linux; 0 elsewhere).
pub fn rss_mib() -> f64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let pages: f64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    pages * 4096.0 / (1024.0 * 1024.0)
}

/// Why a message was skipped: a short kind (the summary's key) and the detail logged.
struct Skip {
    kind: &'static str,
    detail: String,
}

fn skip(kind: &'static str, detail: impl Into<String>) -> Skip {
    Skip {
        kind,
        detail: detail.into(),
    }
}

/// The camera in force: K and the size it was calibrated for.
struct Camera {
    k: [f64; 9],
    size: [u32; 2],
}

fn camera_of(ci: &CameraInfo) -> std::result::Result<Camera, Skip> {
    let k = ci.k;
    if k.iter().any(|v| !v.is_finite()) || k[0] <= 0.0 || k[4] <= 0.0 {
        return Err(skip(
            "camera info without a camera matrix",
            format!("its K {k:?} has no finite, positive focal lengths"),
        ));
    }
    Ok(Camera {
        k,
        size: [ci.width, ci.height],
    })
}

fn decode(m: &Image) -> std::result::Result<Decoded, String> {
    decode_pixels(
        m.width,
        m.height,
        &m.encoding,
        m.is_bigendian != 0,
        m.step as usize,
        &m.data,
    )
}

/// One frame's messages from the objects found: every object with a whole pose or a
/// translation in the 3D array (a TNet's has no rotation: identity, with the rotation's
/// variances -1, ROS's "not estimated"), every detection in the 2D array.
pub fn detection_messages(
    header: &synthgen_ros::msgs::Header,
    objects: &[FoundObject],
    size_of: impl Fn(u32) -> Option<[f64; 3]>,
) -> (Detection3DArray, Detection2DArray) {
    let mut d3 = Detection3DArray {
        header: header.clone(),
        detections: Vec::new(),
    };
    let mut d2 = Detection2DArray {
        header: header.clone(),
        detections: Vec::new(),
    };
    for (i, o) in objects.iter().enumerate() {
        let id = format!("{}_{i}", o.obj_id);
        let hypothesis = ObjectHypothesis {
            class_id: o.obj_id.to_string(),
            score: o.score,
        };
        let [x, y, w, h] = o.bbox;
        d2.detections.push(Detection2D {
            header: header.clone(),
            results: vec![ObjectHypothesisWithPose {
                hypothesis: hypothesis.clone(),
                pose: PoseWithCovariance::default(),
            }],
            bbox: BoundingBox2D {
                center: Pose2D {
                    position: Point2D {
                        x: x + w / 2.0,
                        y: y + h / 2.0,
                    },
                    theta: 0.0,
                },
                size_x: w,
                size_y: h,
            },
            id: id.clone(),
        });
        let Some(t) = o.t else { continue };
        let mut covariance = Covariance::default();
        let orientation = match &o.r {
            Some(r) => quaternion_from_matrix(r),
            None => {
                for i in 3..6 {
                    covariance.0[i * 6 + i] = -1.0;
                }
                Quaternion::default()
            }
        };
        let pose = Pose {
            position: Point {
                x: t[0],
                y: t[1],
                z: t[2],
            },
            orientation,
        };
        let size = size_of(o.obj_id).unwrap_or([0.0; 3]);
        d3.detections.push(Detection3D {
            header: header.clone(),
            results: vec![ObjectHypothesisWithPose {
                hypothesis,
                pose: PoseWithCovariance { pose, covariance },
            }],
            bbox: BoundingBox3D {
                center: pose,
                size: Point {
                    x: size[0],
                    y: size[1],
                    z: size[2],
                },
            },
            id,
        });
    }
    (d3, d2)
}

/// Counts skips and logs them: the first few of each kind in full, then one in a hundred.
struct Skips<'a> {
    log: Log<'a>,
    counts: BTreeMap<String, usize>,
}

impl Skips<'_> {
    fn note(&mut self, s: Skip) {
        let n = self.counts.entry(s.kind.to_string()).or_insert(0);
        *n += 1;
        if *n <= 5 || n.is_multiple_of(100) {
            self.log
                .warning(format!("skipped ({}, {} so far): {}", s.kind, n, s.detail));
        }
    }
}

fn median_p95(v: &mut [f64]) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.95))
}

fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Runs the node until `stop` is set (Ctrl-C), `max_frames` frames or `duration` seconds.
pub fn run_node(
    req: &RosRequest,
    progress: &dyn Progress,
    stop: &AtomicBool,
) -> Result<RosSummary> {
    let log = Log::new(progress);
    crate::use_threads(req.jobs);
    if let Some(path) = &req.record {
        check_apart(
            path,
            &[
                ("model", &req.predictor.model),
                ("detector", &req.predictor.detector),
            ],
        )?;
        if path.exists() && !req.force {
            return Err(user_error(
                format!("{} exists", path.display()),
                "give another --record file, or --force to replace it",
            ));
        }
    }
    if let Some(d) = req.duration {
        if !(d.is_finite() && d > 0.0) {
            return Err(user_error(
                format!("--duration {d} is not a positive number of seconds"),
                "give how long the node runs, e.g. --duration 600",
            ));
        }
    }
    let predictor = Predictor::load(&req.predictor, &log)?;
    let needs_depth = predictor.needs_depth();
    if needs_depth && req.node.depth_topic.is_none() {
        return Err(user_error(
            format!(
                "the {} model reads depth, and no --depth-topic was given",
                predictor.kind().name()
            ),
            "give the depth registered to the colour image, e.g. --depth-topic /camera/aligned_depth_to_color/image_raw",
        ));
    }
    let node = PoseNode::new(&req.node).map_err(|e| {
        user_error(
            format!("the ROS 2 node cannot start: {e}"),
            "check --domain-id, the namespace and the topic names (ROS 2 names: letters, digits, _ and /)",
        )
    })?;
    let mut recorder = match &req.record {
        Some(p) => Some(Recorder::create(
            p,
            &node.topics.detections,
            &node.topics.detections_2d,
        )?),
        None => None,
    };
    let t = &node.topics;
    log.info(format!(
        "node {}/{} on DDS domain {}: subscribes {} (sensor_msgs/Image){} and {} (sensor_msgs/CameraInfo); publishes {} (vision_msgs/Detection3DArray) and {} (vision_msgs/Detection2DArray); the {} model, detector of {} objects",
        req.node.namespace.trim_end_matches('/'),
        req.node.name,
        req.node.domain_id,
        t.image,
        t.depth.as_ref().map(|d| format!(", {d} (depth)")).unwrap_or_default(),
        t.camera_info,
        t.detections,
        t.detections_2d,
        predictor.kind().name(),
        predictor.object_ids().len(),
    ));
    let started = Instant::now();
    let mut skips = Skips {
        log,
        counts: BTreeMap::new(),
    };
    let mut summary = RosSummary::default();
    let mut camera: Option<Camera> = None;
    let mut depth: VecDeque<Image> = VecDeque::new();
    let mut pending: Option<(Image, Instant)> = None;
    let mut last_size: Option<[u32; 2]> = None;
    let mut latencies: Vec<f64> = Vec::new();
    let mut window: Vec<f64> = Vec::new();
    let mut last_status = Instant::now();
    let mut frames_at_status = 0usize;
    loop {
        if stop.load(Ordering::SeqCst)
            || req.max_frames.is_some_and(|n| summary.frames >= n)
            || req
                .duration
                .is_some_and(|d| started.elapsed().as_secs_f64() >= d)
        {
            break;
        }
        let mut received = false;
        loop {
            match node.take_camera_info() {
                Ok(Some(ci)) => {
                    received = true;
                    match camera_of(&ci) {
                        Ok(c) => camera = Some(c),
                        Err(s) => skips.note(s),
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    skips.note(skip(
                        "unreadable message",
                        format!("{}: {e}", t.camera_info),
                    ));
                    break;
                }
            }
        }
        loop {
            match node.take_depth() {
                Ok(Some(d)) => {
                    received = true;
                    depth.push_back(d);
                    if depth.len() > 30 {
                        depth.pop_front();
                    }
                }
                Ok(None) => break,
                Err(e) => {
                    let topic = t.depth.as_deref().unwrap_or("depth");
                    skips.note(skip("unreadable message", format!("{topic}: {e}")));
                    break;
                }
            }
        }
        loop {
            match node.take_image() {
                Ok(Some(m)) => {
                    received = true;
                    if pending.is_some() {
                        summary.replaced += 1;
                    }
                    pending = Some((m, Instant::now()));
                }
                Ok(None) => break,
                Err(e) => {
                    skips.note(skip("unreadable message", format!("{}: {e}", t.image)));
                    break;
                }
            }
        }
        if let Some((img, arrived)) = pending.take() {
            let frame = prepare(
                &img,
                camera.as_ref(),
                &depth,
                needs_depth,
                &mut last_size,
                &log,
            );
            match frame {
                Ok(Some((rgb, d, k))) => {
                    let found =
                        predictor.predict_image(&rgb, d.as_ref(), &k, (0, summary.frames as u32));
                    match found {
                        Ok(f) => {
                            let (d3, d2) = detection_messages(&img.header, &f.objects, |id| {
                                predictor
                                    .object_identity(id)
                                    .map(|o| o.size_mm.map(|v| v / 1000.0))
                            });
                            summary.poses += d3.detections.len();
                            if let Some(r) = recorder.as_mut() {
                                r.record(&d3, &d2, now_ns())?;
                            }
                            if let Err(e) = node.publish(d3, d2) {
                                log.warning(e);
                            }
                            let l = arrived.elapsed().as_secs_f64();
                            // The summary's latencies: the first LATENCIES_KEPT frames (memory
                            // stays flat on a long run); the status lines: their window's.
                            if latencies.len() < LATENCIES_KEPT {
                                latencies.push(l);
                            }
                            window.push(l);
                            summary.frames += 1;
                            if summary.frames == 1 {
                                summary.rss_first_mib = rss_mib();
                            }
                        }
                        Err(e) => skips.note(skip("frame the models refused", format!("{e:#}"))),
                    }
                }
                // Waiting for its depth.
                Ok(None) => {
                    if arrived.elapsed() < DEPTH_WAIT {
                        pending = Some((img, arrived));
                    } else {
                        skips.note(skip(
                            "no depth for the image",
                            format!(
                                "no message on {} within {:.0} ms of the image's stamp {:.6}",
                                t.depth.as_deref().unwrap_or("the depth topic"),
                                DEPTH_PAIRING_S * 1000.0,
                                img.header.stamp.seconds()
                            ),
                        ));
                    }
                }
                Err(s) => skips.note(s),
            }
        }
        if req.status_every > 0.0 && last_status.elapsed().as_secs_f64() >= req.status_every {
            let dt = last_status.elapsed().as_secs_f64();
            let (med, p95) = median_p95(&mut window);
            window.clear();
            log.info(format!(
                "{} frames ({:.1} Hz over the last {:.0} s), latency median {:.0} ms, p95 {:.0} ms in that time; {} replaced by newer, {} skipped; memory {:.0} MiB",
                summary.frames,
                (summary.frames - frames_at_status) as f64 / dt,
                dt,
                med * 1000.0,
                p95 * 1000.0,
                summary.replaced,
                skips.counts.values().sum::<usize>(),
                rss_mib()
            ));
            last_status = Instant::now();
            frames_at_status = summary.frames;
        }
        if !received && pending.is_none() {
            std::thread::sleep(Duration::from_millis(2));
        } else if !received {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    if let Some(r) = recorder {
        r.finish()?;
    }
    let (med, p95) = median_p95(&mut latencies);
    summary.latency_median_s = med;
    summary.latency_p95_s = p95;
    summary.skipped = skips.counts;
    summary.rss_end_mib = rss_mib();
    summary.seconds = started.elapsed().as_secs_f64();
    Ok(summary)
}

/// A colour image ready for the models: its pixels, the depth paired with it, K. `Ok(None)`:
/// its depth has not arrived yet.
#[allow(clippy::type_complexity)]
fn prepare(
    img: &Image,
    camera: Option<&Camera>,
    depth: &VecDeque<Image>,
    needs_depth: bool,
    last_size: &mut Option<[u32; 2]>,
    log: &Log<'_>,
) -> std::result::Result<Option<(RgbImage, Option<Plane<f32>>, [f64; 9])>, Skip> {
    let Some(cam) = camera else {
        return Err(skip(
            "no camera info yet",
            format!(
                "image stamped {:.6}: no CameraInfo received yet",
                img.header.stamp.seconds()
            ),
        ));
    };
    let size = [img.width, img.height];
    if *last_size != Some(size) {
        if let Some(old) = *last_size {
            log.warning(format!(
                "the colour image changed size from {}x{} to {}x{}",
                old[0], old[1], size[0], size[1]
            ));
        }
        *last_size = Some(size);
    }
    if cam.size != [0, 0] && cam.size != size {
        return Err(skip(
            "image size is not its camera info's",
            format!(
                "image {}x{}, camera info {}x{}: K is for another resolution",
                size[0], size[1], cam.size[0], cam.size[1]
            ),
        ));
    }
    let rgb = match decode(img) {
        Ok(Decoded::Colour(c)) => c,
        Ok(Decoded::Depth(_)) => {
            return Err(skip(
                "depth on the colour topic",
                format!("encoding {:?} is depth, not colour", img.encoding),
            ))
        }
        Err(e) => return Err(skip("unreadable image", e)),
    };
    let d = if needs_depth {
        let Some(m) = nearest_in_stamp(depth, img.header.stamp.nanos(), |d| d.header.stamp.nanos())
        else {
            return Ok(None);
        };
        match decode(m) {
            Ok(Decoded::Depth(p)) if [p.width, p.height] == size => Some(p),
            Ok(Decoded::Depth(p)) => {
                return Err(skip(
                    "depth of another size",
                    format!(
                    "depth {}x{}, colour {}x{}: the depth must be registered to the colour image",
                    p.width, p.height, size[0], size[1]
                ),
                ))
            }
            Ok(Decoded::Colour(_)) => {
                return Err(skip(
                    "colour on the depth topic",
                    format!("encoding {:?} is colour, not 16UC1 or 32FC1", m.encoding),
                ))
            }
            Err(e) => return Err(skip("unreadable depth", e)),
        }
    } else {
        None
    };
    Ok(Some((rgb, d, cam.k)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_carry_the_frames_header_and_each_pose() {
        let header = synthgen_ros::msgs::Header {
            stamp: synthgen_ros::msgs::Time { sec: 5, nanosec: 9 },
            frame_id: "camera_color_optical_frame".into(),
        };
        let objects = vec![
            FoundObject {
                obj_id: 5,
                score: 0.9,
                pose_score: 1.0,
                bbox: [10.0, 20.0, 30.0, 40.0],
                r: Some([0., -1., 0., 1., 0., 0., 0., 0., 1.]),
                t: Some([0.1, 0.2, 0.7]),
                segmentation: None,
            },
            // A TNet's: a centre, no rotation.
            FoundObject {
                obj_id: 8,
                score: 0.5,
                pose_score: 1.0,
                bbox: [0.0, 0.0, 2.0, 2.0],
                r: None,
                t: Some([0.0, 0.0, 1.0]),
                segmentation: None,
            },
            // An RNet's: a rotation, no position: a box only.
            FoundObject {
                obj_id: 9,
                score: 0.4,
                pose_score: 1.0,
                bbox: [0.0, 0.0, 2.0, 2.0],
                r: Some([1., 0., 0., 0., 1., 0., 0., 0., 1.]),
                t: None,
                segmentation: None,
            },
        ];
        let (d3, d2) =
            detection_messages(&header, &objects, |id| (id == 5).then_some([0.1, 0.2, 0.3]));
        assert_eq!(d3.header, header);
        assert_eq!(d3.detections.len(), 2);
        assert_eq!(d2.detections.len(), 3);
        let a = &d3.detections[0];
        assert_eq!(a.results[0].hypothesis.class_id, "5");
        assert_eq!(a.results[0].pose.pose.position.z, 0.7);
        let q = a.results[0].pose.pose.orientation;
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((q.z - h).abs() < 1e-12 && (q.w - h).abs() < 1e-12);
        assert_eq!(a.bbox.size.z, 0.3);
        let b = &d3.detections[1];
        assert_eq!(b.results[0].pose.covariance.0[21], -1.0);
        assert_eq!(b.results[0].pose.covariance.0[0], 0.0);
        assert_eq!(d2.detections[0].bbox.center.position.x, 25.0);
        assert_eq!(d2.detections[0].bbox.size_y, 40.0);
        assert_eq!(d2.detections[2].results[0].hypothesis.class_id, "9");
    }
}
