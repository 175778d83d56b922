//! ROS 2 bags in MCAP (`ros2 bag record -s mcap`, the default storage since Iron): the
//! `sensor_msgs/msg/Image`, `CompressedImage` and `CameraInfo` messages of chosen topics,
//! decoded from their CDR encoding (ROS 2's `cdr` message encoding: a 4-byte encapsulation
//! header, little- or big-endian, each primitive aligned to its size from the header's end).
//!
//! [`read_bag`] reads a bag's image, depth and camera-info topics into [`BagFrames`]; the
//! images are kept as their messages' bytes and decoded one at a time ([`BagFrames::frame`]).
//! [`cdr`] writes the same messages (the tests' bags).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use synthgen_formats::bop::{Plane, RgbImage};
use synthgen_formats::{Error, Result};

/// The ROS 2 type names read here.
pub const IMAGE: &str = "sensor_msgs/msg/Image";
pub const COMPRESSED_IMAGE: &str = "sensor_msgs/msg/CompressedImage";
pub const CAMERA_INFO: &str = "sensor_msgs/msg/CameraInfo";

/// A message's `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Header {
    pub sec: i32,
    pub nanosec: u32,
    pub frame_id: String,
}

impl Header {
    /// The stamp in seconds.
    pub fn seconds(&self) -> f64 {
        f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
    }

    fn nanos(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// A decoded `sensor_msgs/msg/Image` (or `CompressedImage`).
#[derive(Debug, Clone, PartialEq)]
pub enum Decoded {
    Colour(RgbImage),
    /// Depth in metres (0 where none): `16UC1` millimetres, `32FC1` metres.
    Depth(Plane<f32>),
}

/// A `sensor_msgs/msg/CameraInfo`: its header, image size and K (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraInfo {
    pub header: Header,
    pub width: u32,
    pub height: u32,
    pub k: [f64; 9],
}

/// One message of a topic read: its header and the message bytes (CDR), decoded on demand.
#[derive(Debug, Clone)]
pub struct RawImage {
    pub header: Header,
    /// The schema: [`IMAGE`] or [`COMPRESSED_IMAGE`].
    pub schema: String,
    /// The message's index among the bag's messages (for errors).
    pub index: usize,
    data: Vec<u8>,
}

/// The frames of a bag: the image topic's messages in order, each with the camera info in
/// force and the depth message nearest in stamp.
#[derive(Debug, Clone)]
pub struct BagFrames {
    pub path: PathBuf,
    pub images: Vec<RawImage>,
    pub depth: Vec<RawImage>,
    pub camera_infos: Vec<CameraInfo>,
    /// Every topic of the bag with its schema name and message count.
    pub topics: BTreeMap<String, (String, usize)>,
}

/// Depth and colour whose stamps differ by more than this are not one frame (seconds).
pub const DEPTH_PAIRING_S: f64 = 0.05;

/// Of `items`, the one whose stamp (`stamp`, nanoseconds) is nearest `t_ns`, if within
/// [`DEPTH_PAIRING_S`]: a colour image's depth, in a bag or as the node receives them.
pub fn nearest_in_stamp<'a, T>(
    items: impl IntoIterator<Item = &'a T>,
    t_ns: i64,
    stamp: impl Fn(&T) -> i64,
) -> Option<&'a T> {
    items
        .into_iter()
        .min_by_key(|d| (stamp(d) - t_ns).abs())
        .filter(|d| ((stamp(d) - t_ns).abs() as f64) * 1e-9 <= DEPTH_PAIRING_S)
}

impl BagFrames {
    /// The camera info for an image: the last one stamped at or before it, else the first.
    pub fn camera_for(&self, image: &RawImage) -> Option<&CameraInfo> {
        let t = image.header.nanos();
        self.camera_infos
            .iter()
            .rev()
            .find(|c| c.header.nanos() <= t)
            .or_else(|| self.camera_infos.first())
    }

    /// The depth message nearest in stamp to `image`, within [`DEPTH_PAIRING_S`].
    pub fn depth_for(&self, image: &RawImage) -> Option<&RawImage> {
        nearest_in_stamp(&self.depth, image.header.nanos(), |d| d.header.nanos())
    }

    /// Decodes an image message (colour, or depth on a depth topic).
    pub fn decode(&self, m: &RawImage) -> Result<Decoded> {
        decode_image(&m.schema, &m.data).map_err(|e| {
            Error::malformed(
                &self.path,
                format!(
                    "message {} ({}, stamp {:.6}): {e}",
                    m.index,
                    m.schema,
                    m.header.seconds()
                ),
            )
        })
    }
}

/// Reads the messages of `image_topic`, `depth_topic` and `camera_info_topic` from an MCAP
/// file. A topic of another type than the one asked for, or an image topic without a message,
/// is an error naming the bag and listing its topics.
pub fn read_bag(
    path: &Path,
    image_topic: &str,
    depth_topic: Option<&str>,
    camera_info_topic: &str,
) -> Result<BagFrames> {
    let bytes = std::fs::read(path).map_err(|e| Error::io("read", path, e))?;
    let stream = mcap::MessageStream::new(&bytes)
        .map_err(|e| Error::malformed(path, format!("not an MCAP file: {e}")))?;
    let mut out = BagFrames {
        path: path.to_path_buf(),
        images: Vec::new(),
        depth: Vec::new(),
        camera_infos: Vec::new(),
        topics: BTreeMap::new(),
    };
    for (index, m) in stream.enumerate() {
        let m = m.map_err(|e| Error::malformed(path, format!("message {index}: {e}")))?;
        let schema = m
            .channel
            .schema
            .as_ref()
            .map_or_else(String::new, |s| s.name.clone());
        let topic = m.channel.topic.as_str();
        let e = out
            .topics
            .entry(topic.to_string())
            .or_insert((schema.clone(), 0));
        e.1 += 1;
        let wanted_image = topic == image_topic || Some(topic) == depth_topic;
        if !wanted_image && topic != camera_info_topic {
            continue;
        }
        if m.channel.message_encoding != "cdr" {
            return Err(Error::malformed(
                path,
                format!(
                    "topic {topic} is encoded as {:?}; ROS 2 bags encode as \"cdr\"",
                    m.channel.message_encoding
                ),
            ));
        }
        let bad =
            |what: String| Error::malformed(path, format!("message {index} on {topic}: {what}"));
        if wanted_image {
            if schema != IMAGE && schema != COMPRESSED_IMAGE {
                return Err(bad(format!(
                    "its type is {schema:?}, not {IMAGE} or {COMPRESSED_IMAGE}"
                )));
            }
            let header = Cdr::new(&m.data)
                .and_then(|mut c| c.header())
                .map_err(bad)?;
            let raw = RawImage {
                header,
                schema,
                index,
                data: m.data.into_owned(),
            };
            if topic == image_topic {
                out.images.push(raw);
            } else {
                out.depth.push(raw);
            }
        } else {
            if schema != CAMERA_INFO {
                return Err(bad(format!("its type is {schema:?}, not {CAMERA_INFO}")));
            }
            out.camera_infos
                .push(decode_camera_info(&m.data).map_err(bad)?);
        }
    }
    let listing = || {
        out.topics
            .iter()
            .map(|(t, (s, n))| format!("{t} ({s}, {n})"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if out.images.is_empty() {
        return Err(Error::malformed(
            path,
            format!(
                "no message on the image topic {image_topic}; its topics: {}",
                listing()
            ),
        ));
    }
    if out.camera_infos.is_empty() {
        return Err(Error::malformed(
            path,
            format!(
                "no message on the camera info topic {camera_info_topic}; its topics: {}",
                listing()
            ),
        ));
    }
    out.camera_infos.sort_by_key(|c| c.header.nanos());
    Ok(out)
}

/// A CDR reader (ROS 2's XCDR1: alignment from the end of the encapsulation header).
struct Cdr<'a> {
    data: &'a [u8],
    pos: usize,
    little: bool,
}

impl<'a> Cdr<'a> {
    fn new(data: &'a [u8]) -> std::result::Result<Cdr<'a>, String> {
        if data.len() < 4 {
            return Err("shorter than its CDR header".into());
        }
        let little = match (data[0], data[1]) {
            (0, 1) | (0, 3) => true,
            (0, 0) | (0, 2) => false,
            (a, b) => return Err(format!("unknown CDR encapsulation {a:#04x}{b:02x}")),
        };
        Ok(Cdr {
            data: &data[4..],
            pos: 0,
            little,
        })
    }

    fn take(&mut self, n: usize, align: usize) -> std::result::Result<&'a [u8], String> {
        self.pos = self.pos.div_ceil(align) * align;
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len());
        let Some(end) = end else {
            return Err(format!(
                "truncated: {n} bytes wanted at {} of {}",
                self.pos,
                self.data.len()
            ));
        };
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn u32(&mut self) -> std::result::Result<u32, String> {
        let b: [u8; 4] = self.take(4, 4)?.try_into().map_err(|_| "u32")?;
        Ok(if self.little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    fn i32(&mut self) -> std::result::Result<i32, String> {
        Ok(self.u32()? as i32)
    }

    fn u8(&mut self) -> std::result::Result<u8, String> {
        Ok(self.take(1, 1)?[0])
    }

    fn f64(&mut self) -> std::result::Result<f64, String> {
        let b: [u8; 8] = self.take(8, 8)?.try_into().map_err(|_| "f64")?;
        Ok(if self.little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        })
    }

    fn string(&mut self) -> std::result::Result<String, String> {
        let n = self.u32()? as usize;
        let b = self.take(n, 1)?;
        // The length counts the terminating NUL.
        let b = b.strip_suffix(&[0]).unwrap_or(b);
        String::from_utf8(b.to_vec()).map_err(|_| "a string that is not UTF-8".to_string())
    }

    fn bytes(&mut self) -> std::result::Result<&'a [u8], String> {
        let n = self.u32()? as usize;
        self.take(n, 1)
    }

    fn header(&mut self) -> std::result::Result<Header, String> {
        Ok(Header {
            sec: self.i32()?,
            nanosec: self.u32()?,
            frame_id: self.string()?,
        })
    }
}

fn decode_camera_info(data: &[u8]) -> std::result::Result<CameraInfo, String> {
    let mut c = Cdr::new(data)?;
    let header = c.header()?;
    let height = c.u32()?;
    let width = c.u32()?;
    let _distortion_model = c.string()?;
    let n = c.u32()? as usize;
    for _ in 0..n {
        c.f64()?;
    }
    let mut k = [0.0; 9];
    for v in &mut k {
        *v = c.f64()?;
    }
    if k.iter().any(|v| !v.is_finite()) || k[0] <= 0.0 || k[4] <= 0.0 {
        return Err(format!(
            "its K {k:?} is not a camera's (finite, positive focal lengths)"
        ));
    }
    Ok(CameraInfo {
        header,
        width,
        height,
        k,
    })
}

/// Decodes an `Image` (rgb8, bgr8, rgba8, bgra8, mono8; depth 16UC1 in mm, 32FC1 in metres)
/// or a `CompressedImage` (JPEG or PNG colour).
fn decode_image(schema: &str, data: &[u8]) -> std::result::Result<Decoded, String> {
    let mut c = Cdr::new(data)?;
    let _header = c.header()?;
    if schema == COMPRESSED_IMAGE {
        let format = c.string()?;
        let bytes = c.bytes()?;
        if format.contains("compressedDepth") {
            return Err(format!(
                "format {format:?}: compressedDepth is not read; record the raw depth topic"
            ));
        }
        let img = image::load_from_memory(bytes)
            .map_err(|e| format!("format {format:?}: {e}"))?
            .to_rgb8();
        return Ok(Decoded::Colour(RgbImage {
            width: img.width(),
            height: img.height(),
            rgb: img.into_raw(),
        }));
    }
    let height = c.u32()?;
    let width = c.u32()?;
    let encoding = c.string()?;
    let big = c.u8()? != 0;
    let step = c.u32()? as usize;
    let pixels = c.bytes()?;
    decode_pixels(width, height, &encoding, big, step, pixels)
}

/// Decodes an `Image`'s pixels: rgb8, bgr8, rgba8, bgra8, mono8 colour; depth 16UC1 in mm,
/// 32FC1 in metres (0 where none).
pub fn decode_pixels(
    width: u32,
    height: u32,
    encoding: &str,
    big: bool,
    step: usize,
    pixels: &[u8],
) -> std::result::Result<Decoded, String> {
    let (w, h) = (width as usize, height as usize);
    let bpp = match encoding {
        "rgb8" | "bgr8" => 3,
        "rgba8" | "bgra8" => 4,
        "mono8" | "8UC1" => 1,
        "16UC1" | "mono16" => 2,
        "32FC1" => 4,
        other => {
            return Err(format!(
            "encoding {other:?} is not read (rgb8, bgr8, rgba8, bgra8, mono8; depth 16UC1, 32FC1)"
        ))
        }
    };
    if w == 0 || h == 0 || step < w * bpp || pixels.len() < step * (h - 1) + w * bpp {
        return Err(format!(
            "{width}x{height} {encoding} with step {step} needs {} bytes, and the message has {}",
            step * h,
            pixels.len()
        ));
    }
    let row = |y: usize| &pixels[y * step..y * step + w * bpp];
    Ok(match encoding {
        "16UC1" | "mono16" | "32FC1" => {
            let mut data = Vec::with_capacity(w * h);
            for y in 0..h {
                for p in row(y).chunks_exact(bpp) {
                    let v = if bpp == 2 {
                        let b = [p[0], p[1]];
                        f32::from(if big {
                            u16::from_be_bytes(b)
                        } else {
                            u16::from_le_bytes(b)
                        }) / 1000.0
                    } else {
                        let b = [p[0], p[1], p[2], p[3]];
                        let v = if big {
                            f32::from_be_bytes(b)
                        } else {
                            f32::from_le_bytes(b)
                        };
                        if v.is_finite() && v > 0.0 {
                            v
                        } else {
                            0.0
                        }
                    };
                    data.push(v);
                }
            }
            Decoded::Depth(Plane {
                width,
                height,
                data,
            })
        }
        enc => {
            let mut rgb = Vec::with_capacity(w * h * 3);
            for y in 0..h {
                for p in row(y).chunks_exact(bpp) {
                    match enc {
                        "rgb8" | "rgba8" => rgb.extend_from_slice(&p[..3]),
                        "bgr8" | "bgra8" => rgb.extend_from_slice(&[p[2], p[1], p[0]]),
                        _ => rgb.extend_from_slice(&[p[0]; 3]),
                    }
                }
            }
            Decoded::Colour(RgbImage { width, height, rgb })
        }
    })
}

/// Writing the messages read here, little-endian CDR (ROS 2's default), and their schemas
/// (`ros2msg` definitions as `ros2 bag record` stores them).
pub mod cdr {
    use super::Header;

    /// A CDR writer.
    #[derive(Default)]
    pub struct Writer {
        buf: Vec<u8>,
    }

    impl Writer {
        pub fn new() -> Writer {
            Writer { buf: Vec::new() }
        }

        fn align(&mut self, n: usize) {
            while !self.buf.len().is_multiple_of(n) {
                self.buf.push(0);
            }
        }

        pub fn u32(&mut self, v: u32) {
            self.align(4);
            self.buf.extend_from_slice(&v.to_le_bytes());
        }

        pub fn i32(&mut self, v: i32) {
            self.align(4);
            self.buf.extend_from_slice(&v.to_le_bytes());
        }

        pub fn u8(&mut self, v: u8) {
            self.buf.push(v);
        }

        pub fn f64(&mut self, v: f64) {
            self.align(8);
            self.buf.extend_from_slice(&v.to_le_bytes());
        }

        pub fn f32(&mut self, v: f32) {
            self.align(4);
            self.buf.extend_from_slice(&v.to_le_bytes());
        }

        pub fn string(&mut self, s: &str) {
            self.u32(s.len() as u32 + 1);
            self.buf.extend_from_slice(s.as_bytes());
            self.buf.push(0);
        }

        pub fn bytes(&mut self, b: &[u8]) {
            self.u32(b.len() as u32);
            self.buf.extend_from_slice(b);
        }

        pub fn header(&mut self, h: &Header) {
            self.i32(h.sec);
            self.u32(h.nanosec);
            self.string(&h.frame_id);
        }

        /// The message: the little-endian encapsulation header and the body.
        pub fn finish(self) -> Vec<u8> {
            let mut out = vec![0, 1, 0, 0];
            out.extend(self.buf);
            out
        }
    }

    /// A `sensor_msgs/msg/Image`.
    pub fn image(
        h: &Header,
        width: u32,
        height: u32,
        encoding: &str,
        step: u32,
        data: &[u8],
    ) -> Vec<u8> {
        let mut w = Writer::new();
        w.header(h);
        w.u32(height);
        w.u32(width);
        w.string(encoding);
        w.u8(0);
        w.u32(step);
        w.bytes(data);
        w.finish()
    }

    /// A `sensor_msgs/msg/CameraInfo` of a pinhole camera without distortion.
    pub fn camera_info(h: &Header, width: u32, height: u32, k: &[f64; 9]) -> Vec<u8> {
        let mut w = Writer::new();
        w.header(h);
        w.u32(height);
        w.u32(width);
        w.string("plumb_bob");
        w.u32(5);
        for _ in 0..5 {
            w.f64(0.0);
        }
        for v in k {
            w.f64(*v);
        }
        for v in [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0] {
            w.f64(v);
        }
        let p = [
            k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0,
        ];
        for v in p {
            w.f64(v);
        }
        w.u32(0);
        w.u32(0);
        for _ in 0..4 {
            w.u32(0);
        }
        w.u8(0);
        w.finish()
    }

    /// `ros2msg` schema texts, as rosbag2 stores them (the type, then its dependencies).
    pub const HEADER_DEFS: &str = "================================================================================\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n================================================================================\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
    pub fn image_schema() -> String {
        format!("std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n{HEADER_DEFS}")
    }
    pub fn camera_info_schema() -> String {
        format!("std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi\n{HEADER_DEFS}================================================================================\nMSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n")
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use std::collections::BTreeMap as Map;

    fn bag(dir: &Path, frames: &[(i32, Vec<u8>, &str)], with_info: bool) -> PathBuf {
        let path = dir.join("t.mcap");
        let f = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let mut w = mcap::Writer::new(f).unwrap();
        let si = w
            .add_schema(IMAGE, "ros2msg", cdr::image_schema().as_bytes())
            .unwrap();
        let sc = w
            .add_schema(CAMERA_INFO, "ros2msg", cdr::camera_info_schema().as_bytes())
            .unwrap();
        let ci = w.add_channel(si, "/cam/color", "cdr", &Map::new()).unwrap();
        let cd = w.add_channel(si, "/cam/depth", "cdr", &Map::new()).unwrap();
        let cc = w.add_channel(sc, "/cam/info", "cdr", &Map::new()).unwrap();
        let k = [500.0, 0.0, 2.0, 0.0, 500.0, 1.5, 0.0, 0.0, 1.0];
        for (seq, (sec, data, enc)) in frames.iter().enumerate() {
            let h = Header {
                sec: *sec,
                nanosec: 0,
                frame_id: "cam".into(),
            };
            let (chan, step) = match *enc {
                "16UC1" => (cd, 8),
                _ => (ci, 12),
            };
            let msg = cdr::image(&h, 4, 3, enc, step, data);
            let t = *sec as u64 * 1_000_000_000;
            w.write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: chan,
                    sequence: seq as u32,
                    log_time: t,
                    publish_time: t,
                },
                &msg,
            )
            .unwrap();
            if with_info && seq == 0 {
                let info = cdr::camera_info(&h, 4, 3, &k);
                w.write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: cc,
                        sequence: 0,
                        log_time: t,
                        publish_time: t,
                    },
                    &info,
                )
                .unwrap();
            }
        }
        w.finish().unwrap();
        path
    }

    #[test]
    fn images_depth_and_camera_info_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let bgr: Vec<u8> = (0..36).map(|i| i as u8).collect();
        let depth: Vec<u8> = (0..12u16).flat_map(|i| (i * 100).to_le_bytes()).collect();
        let path = bag(
            dir.path(),
            &[
                (10, bgr.clone(), "bgr8"),
                (10, depth.clone(), "16UC1"),
                (11, bgr.clone(), "bgr8"),
            ],
            true,
        );
        let b = read_bag(&path, "/cam/color", Some("/cam/depth"), "/cam/info").unwrap();
        assert_eq!(b.images.len(), 2);
        assert_eq!(b.topics["/cam/color"], (IMAGE.to_string(), 2));
        let info = b.camera_for(&b.images[1]).unwrap();
        assert_eq!(
            (info.width, info.height, info.k[0], info.k[5]),
            (4, 3, 500.0, 1.5)
        );
        let Decoded::Colour(c) = b.decode(&b.images[0]).unwrap() else {
            panic!("colour")
        };
        // bgr8 → rgb.
        assert_eq!(&c.rgb[..6], &[2, 1, 0, 5, 4, 3]);
        let d = b.depth_for(&b.images[0]).unwrap();
        let Decoded::Depth(p) = b.decode(d).unwrap() else {
            panic!("depth")
        };
        assert!((p.data[5] - 0.5).abs() < 1e-6);
        // 1 s apart: no depth for the second image.
        assert!(b.depth_for(&b.images[1]).is_none());
        assert_eq!(b.images[1].header.seconds(), 11.0);

        // A wrong topic, a missing camera info, a truncated message: errors naming the bag.
        let e = read_bag(&path, "/nope", None, "/cam/info")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.mcap") && e.contains("/cam/color (sensor_msgs/msg/Image, 2)"),
            "{e}"
        );
        let e = read_bag(&path, "/cam/info", None, "/cam/info")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not sensor_msgs/msg/Image"), "{e}");
        let no_info = bag(dir.path(), &[(1, bgr.clone(), "bgr8")], false);
        let e = read_bag(&no_info, "/cam/color", None, "/cam/info")
            .unwrap_err()
            .to_string();
        assert!(e.contains("camera info topic"), "{e}");
        let short = bag(dir.path(), &[(1, bgr[..20].to_vec(), "bgr8")], true);
        let b = read_bag(&short, "/cam/color", None, "/cam/info").unwrap();
        let e = b.decode(&b.images[0]).unwrap_err().to_string();
        assert!(e.contains("needs 36 bytes"), "{e}");
        let odd = bag(dir.path(), &[(1, bgr, "yuv422")], true);
        let b = read_bag(&odd, "/cam/color", None, "/cam/info").unwrap();
        assert!(b
            .decode(&b.images[0])
            .unwrap_err()
            .to_string()
            .contains("yuv422"));
        std::fs::write(dir.path().join("x.mcap"), b"not a bag").unwrap();
        assert!(read_bag(&dir.path().join("x.mcap"), "/a", None, "/b").is_err());
    }
}
