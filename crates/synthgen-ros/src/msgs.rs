//! The ROS 2 messages the node reads and publishes, as serde types whose field order is the
//! messages' (`sensor_msgs` and `vision_msgs` 4.x, as in Humble and Jazzy): serialized in
//! CDR by the DDS layer (`ros2-client`) and by [`to_cdr`] for the `--record` bag, with their
//! `ros2msg` schemas ([`schema`]) as `ros2 bag record` stores them.

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::ser::{SerializeTuple, Serializer};
use serde::{Deserialize, Serialize};

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// The stamp in seconds.
    pub fn seconds(&self) -> f64 {
        f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
    }

    /// The stamp in nanoseconds.
    pub fn nanos(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `sensor_msgs/Image`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Image {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub is_bigendian: u8,
    pub step: u32,
    #[serde(with = "byte_seq")]
    pub data: Vec<u8>,
}

/// `sensor_msgs/RegionOfInterest`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct RegionOfInterest {
    pub x_offset: u32,
    pub y_offset: u32,
    pub height: u32,
    pub width: u32,
    pub do_rectify: bool,
}

/// `sensor_msgs/CameraInfo`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CameraInfo {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub distortion_model: String,
    pub d: Vec<f64>,
    pub k: [f64; 9],
    pub r: [f64; 9],
    pub p: [f64; 12],
    pub binning_x: u32,
    pub binning_y: u32,
    pub roi: RegionOfInterest,
}

/// `geometry_msgs/Point` (and `Vector3`: the same fields).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Quaternion {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    pub position: Point,
    pub orientation: Quaternion,
}

/// `geometry_msgs/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    pub pose: Pose,
    pub covariance: Covariance,
}

/// A `float64[36]` (serde has no arrays over 32).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Covariance {
        Covariance([0.0; 36])
    }
}

/// `vision_msgs/ObjectHypothesis`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ObjectHypothesis {
    pub class_id: String,
    pub score: f64,
}

/// `vision_msgs/ObjectHypothesisWithPose`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ObjectHypothesisWithPose {
    pub hypothesis: ObjectHypothesis,
    pub pose: PoseWithCovariance,
}

/// `vision_msgs/BoundingBox3D`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct BoundingBox3D {
    pub center: Pose,
    pub size: Point,
}

/// `vision_msgs/Detection3D`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Detection3D {
    pub header: Header,
    pub results: Vec<ObjectHypothesisWithPose>,
    pub bbox: BoundingBox3D,
    pub id: String,
}

/// `vision_msgs/Detection3DArray`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Detection3DArray {
    pub header: Header,
    pub detections: Vec<Detection3D>,
}

/// `vision_msgs/Point2D`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Point2D {
    pub x: f64,
    pub y: f64,
}

/// `vision_msgs/Pose2D`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose2D {
    pub position: Point2D,
    pub theta: f64,
}

/// `vision_msgs/BoundingBox2D`: the centre and the size in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct BoundingBox2D {
    pub center: Pose2D,
    pub size_x: f64,
    pub size_y: f64,
}

/// `vision_msgs/Detection2D`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Detection2D {
    pub header: Header,
    pub results: Vec<ObjectHypothesisWithPose>,
    pub bbox: BoundingBox2D,
    pub id: String,
}

/// `vision_msgs/Detection2DArray`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Detection2DArray {
    pub header: Header,
    pub detections: Vec<Detection2D>,
}

impl Serialize for Covariance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Covariance, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (i, v) in c.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, V)
    }
}

/// A `uint8[]` read and written as one block (CDR's sequence: a count, then the bytes), not
/// byte by byte: an image's megabyte.
mod byte_seq {
    use super::*;

    pub fn serialize<S: Serializer>(v: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(v)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u8>, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Vec<u8>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a uint8 sequence")
            }
            fn visit_bytes<E: de::Error>(self, v: &[u8]) -> Result<Vec<u8>, E> {
                Ok(v.to_vec())
            }
            fn visit_byte_buf<E: de::Error>(self, v: Vec<u8>) -> Result<Vec<u8>, E> {
                Ok(v)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<u8>, A::Error> {
                let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0));
                while let Some(b) = seq.next_element()? {
                    out.push(b);
                }
                Ok(out)
            }
        }
        d.deserialize_byte_buf(V)
    }
}

/// A message in ROS 2's CDR (little-endian, with its 4-byte encapsulation header): what a
/// bag's `cdr` message encoding holds.
pub fn to_cdr<T: Serialize>(m: &T) -> Result<Vec<u8>, String> {
    let body = cdr_encoding::to_vec::<T, byteorder::LittleEndian>(m).map_err(|e| e.to_string())?;
    let mut out = Vec::with_capacity(body.len() + 4);
    out.extend_from_slice(&[0, 1, 0, 0]);
    out.extend_from_slice(&body);
    Ok(out)
}

/// A message from ROS 2's CDR (either byte order), as [`to_cdr`] writes it.
pub fn from_cdr<T: for<'de> Deserialize<'de>>(data: &[u8]) -> Result<T, String> {
    if data.len() < 4 {
        return Err("shorter than its CDR header".into());
    }
    let body = &data[4..];
    let r = match (data[0], data[1]) {
        (0, 1) | (0, 3) => cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(body),
        (0, 0) | (0, 2) => cdr_encoding::from_bytes::<T, byteorder::BigEndian>(body),
        (a, b) => return Err(format!("unknown CDR encapsulation {a:#04x}{b:02x}")),
    };
    r.map(|(m, _)| m).map_err(|e| e.to_string())
}

const HEADER: &str = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n";
const TIME: &str = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
const POSE: &str =
    "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n";
const POINT: &str = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n";
const QUATERNION: &str =
    "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n";
const HYPOTHESIS_WITH_POSE: &str = "MSG: vision_msgs/ObjectHypothesisWithPose\nvision_msgs/ObjectHypothesis hypothesis\ngeometry_msgs/PoseWithCovariance pose\n";
const HYPOTHESIS: &str = "MSG: vision_msgs/ObjectHypothesis\nstring class_id\nfloat64 score\n";
const POSE_COV: &str =
    "MSG: geometry_msgs/PoseWithCovariance\ngeometry_msgs/Pose pose\nfloat64[36] covariance\n";

/// The `ros2msg` schema of a type published or recorded here (the message's definition, then
/// each type it uses after a line of `=`), as `ros2 bag record` writes it to an MCAP schema.
pub fn schema(type_name: &str) -> Option<String> {
    let join = |main: &str, deps: &[&str]| {
        let sep = format!("{}\n", "=".repeat(80));
        let mut s = main.to_string();
        for d in deps {
            s.push_str(&sep);
            s.push_str(d);
        }
        s
    };
    Some(match type_name {
        DETECTION_3D_ARRAY => join(
            "std_msgs/Header header\nvision_msgs/Detection3D[] detections\n",
            &[
                HEADER,
                TIME,
                "MSG: vision_msgs/Detection3D\nstd_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\nvision_msgs/BoundingBox3D bbox\nstring id\n",
                HYPOTHESIS_WITH_POSE,
                HYPOTHESIS,
                POSE_COV,
                POSE,
                POINT,
                QUATERNION,
                "MSG: vision_msgs/BoundingBox3D\ngeometry_msgs/Pose center\ngeometry_msgs/Vector3 size\n",
                "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n",
            ],
        ),
        DETECTION_2D_ARRAY => join(
            "std_msgs/Header header\nvision_msgs/Detection2D[] detections\n",
            &[
                HEADER,
                TIME,
                "MSG: vision_msgs/Detection2D\nstd_msgs/Header header\nvision_msgs/ObjectHypothesisWithPose[] results\nvision_msgs/BoundingBox2D bbox\nstring id\n",
                HYPOTHESIS_WITH_POSE,
                HYPOTHESIS,
                POSE_COV,
                POSE,
                POINT,
                QUATERNION,
                "MSG: vision_msgs/BoundingBox2D\nvision_msgs/Pose2D center\nfloat64 size_x\nfloat64 size_y\n",
                "MSG: vision_msgs/Pose2D\nvision_msgs/Point2D position\nfloat64 theta\n",
                "MSG: vision_msgs/Point2D\nfloat64 x\nfloat64 y\n",
            ],
        ),
        _ => return None,
    })
}

/// The ROS 2 type names published.
pub const DETECTION_3D_ARRAY: &str = "vision_msgs/msg/Detection3DArray";
pub const DETECTION_2D_ARRAY: &str = "vision_msgs/msg/Detection2DArray";

/// A rotation matrix (row-major) as a unit quaternion (Shepperd's method: the largest of the
/// four candidates, so no division by a small number).
pub fn quaternion_from_matrix(r: &[f64; 9]) -> Quaternion {
    let (m00, m01, m02, m10, m11, m12, m20, m21, m22) =
        (r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]);
    let tr = m00 + m11 + m22;
    let (x, y, z, w) = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        ((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s)
    } else if m00 > m11 && m00 > m22 {
        let s = (1.0 + m00 - m11 - m22).sqrt() * 2.0;
        (0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s)
    } else if m11 > m22 {
        let s = (1.0 + m11 - m00 - m22).sqrt() * 2.0;
        ((m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s)
    } else {
        let s = (1.0 + m22 - m00 - m11).sqrt() * 2.0;
        ((m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s)
    };
    let n = (x * x + y * y + z * z + w * w).sqrt();
    // w ≥ 0: one of the two quaternions of a rotation, always the same one.
    let sign = if w < 0.0 { -1.0 } else { 1.0 } / n;
    Quaternion {
        x: x * sign,
        y: y * sign,
        z: z * sign,
        w: w * sign,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_round_trip_through_cdr_with_ros_layout() {
        let img = Image {
            header: Header {
                stamp: Time {
                    sec: 12,
                    nanosec: 345,
                },
                frame_id: "cam".into(),
            },
            height: 2,
            width: 3,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: 9,
            data: (0..18).collect(),
        };
        let bytes = to_cdr(&img).unwrap();
        // The layout the bag reader (its own CDR reader, not serde's) decodes.
        let ours = crate::rosbag::cdr::image(
            &crate::rosbag::Header {
                sec: 12,
                nanosec: 345,
                frame_id: "cam".into(),
            },
            3,
            2,
            "rgb8",
            9,
            &(0..18).collect::<Vec<u8>>(),
        );
        assert_eq!(bytes, ours);
        assert_eq!(from_cdr::<Image>(&bytes).unwrap(), img);

        let mut d = Detection3DArray::default();
        d.detections.push(Detection3D {
            results: vec![ObjectHypothesisWithPose {
                hypothesis: ObjectHypothesis {
                    class_id: "5".into(),
                    score: 0.5,
                },
                pose: PoseWithCovariance {
                    covariance: Covariance([1.5; 36]),
                    ..Default::default()
                },
            }],
            id: "x".into(),
            ..Default::default()
        });
        let b = to_cdr(&d).unwrap();
        assert_eq!(from_cdr::<Detection3DArray>(&b).unwrap(), d);
        // 36 doubles, not a counted sequence: header(4+4+4+1 -> 16) + count 4 + ...
        assert!(b.len() > 36 * 8);
    }

    #[test]
    fn quaternions_of_rotations() {
        let id = quaternion_from_matrix(&[1., 0., 0., 0., 1., 0., 0., 0., 1.]);
        assert_eq!((id.x, id.y, id.z, id.w), (0.0, 0.0, 0.0, 1.0));
        // 180° about x: the trace is -1, the first branch cannot be used.
        let q = quaternion_from_matrix(&[1., 0., 0., 0., -1., 0., 0., 0., -1.]);
        assert!((q.x.abs() - 1.0).abs() < 1e-12 && q.w.abs() < 1e-12);
        // 90° about z.
        let q = quaternion_from_matrix(&[0., -1., 0., 1., 0., 0., 0., 0., 1.]);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((q.z - h).abs() < 1e-12 && (q.w - h).abs() < 1e-12);
    }
}
