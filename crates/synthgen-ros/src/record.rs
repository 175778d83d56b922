//! `synthgen ros --record out.mcap`: what the node published, as a ROS 2 bag in MCAP (the
//! `ros2msg` schemas and `cdr` messages of `ros2 bag record -s mcap`), readable by
//! `ros2 bag play`, Foxglove, the `mcap` and `rosbags` Python libraries, and by us.
//!
//! Messages go to the file as they are published; the chunk in progress is written out every
//! [`FLUSH_EVERY`], so a node killed hard loses at most that much (the summary at the end,
//! written by [`Recorder::finish`], only speeds up readers).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use synthgen_formats::{Error, Result};

use crate::msgs::{self, Detection2DArray, Detection3DArray};

/// How often the chunk in progress is written out.
pub const FLUSH_EVERY: Duration = Duration::from_secs(1);

/// An MCAP file being recorded.
pub struct Recorder {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<File>>,
    channel_3d: u16,
    channel_2d: u16,
    sequence: u32,
    last_flush: Instant,
    /// Messages written.
    pub messages: usize,
}

fn mcap_error(path: &Path, e: mcap::McapError) -> Error {
    Error::malformed(path, format!("cannot write the MCAP bag: {e}"))
}

impl Recorder {
    /// Creates `path` (an existing file is the caller's to refuse) with the two detection
    /// topics as channels.
    pub fn create(path: &Path, topic_3d: &str, topic_2d: &str) -> Result<Recorder> {
        let file = File::create(path).map_err(|e| Error::io("create", path, e))?;
        // The "ros2" profile, as rosbag2's MCAP storage writes it (rosbags refuses others).
        let mut writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("synthgen ", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(|e| mcap_error(path, e))?;
        let mut channel = |ty: &str, topic: &str| -> Result<u16> {
            let schema = msgs::schema(ty)
                .ok_or_else(|| Error::malformed(path, format!("no schema for {ty}")))?;
            let id = writer
                .add_schema(ty, "ros2msg", schema.as_bytes())
                .map_err(|e| mcap_error(path, e))?;
            writer
                .add_channel(id, topic, "cdr", &BTreeMap::new())
                .map_err(|e| mcap_error(path, e))
        };
        let channel_3d = channel(msgs::DETECTION_3D_ARRAY, topic_3d)?;
        let channel_2d = channel(msgs::DETECTION_2D_ARRAY, topic_2d)?;
        Ok(Recorder {
            path: path.to_path_buf(),
            writer,
            channel_3d,
            channel_2d,
            sequence: 0,
            last_flush: Instant::now(),
            messages: 0,
        })
    }

    /// Records one frame's published messages; `log_time_ns` is when they were published.
    pub fn record(
        &mut self,
        d3: &Detection3DArray,
        d2: &Detection2DArray,
        log_time_ns: u64,
    ) -> Result<()> {
        let publish = u64::try_from(d3.header.stamp.nanos()).unwrap_or(log_time_ns);
        for (channel, data) in [
            (self.channel_3d, msgs::to_cdr(d3)),
            (self.channel_2d, msgs::to_cdr(d2)),
        ] {
            let data = data.map_err(|e| Error::malformed(&self.path, e))?;
            self.sequence += 1;
            self.writer
                .write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: channel,
                        sequence: self.sequence,
                        log_time: log_time_ns,
                        publish_time: publish,
                    },
                    &data,
                )
                .map_err(|e| mcap_error(&self.path, e))?;
            self.messages += 1;
        }
        if self.last_flush.elapsed() >= FLUSH_EVERY {
            self.writer.flush().map_err(|e| mcap_error(&self.path, e))?;
            self.last_flush = Instant::now();
        }
        Ok(())
    }

    /// Writes the summary and closes the file.
    pub fn finish(mut self) -> Result<()> {
        self.writer
            .finish()
            .map_err(|e| mcap_error(&self.path, e))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::*;

    #[test]
    fn recorded_detections_read_back_with_their_schemas() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.mcap");
        let mut r = Recorder::create(&path, "/detections", "/detections_2d").unwrap();
        let header = Header {
            stamp: Time { sec: 3, nanosec: 7 },
            frame_id: "camera".into(),
        };
        let d3 = Detection3DArray {
            header: header.clone(),
            detections: vec![Detection3D {
                header: header.clone(),
                id: "1".into(),
                ..Default::default()
            }],
        };
        let d2 = Detection2DArray {
            header,
            detections: vec![],
        };
        r.record(&d3, &d2, 42).unwrap();
        r.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut seen = Vec::new();
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let m = m.unwrap();
            let schema = m.channel.schema.as_ref().unwrap();
            assert_eq!(schema.encoding, "ros2msg");
            assert_eq!(m.channel.message_encoding, "cdr");
            seen.push((m.channel.topic.clone(), schema.name.clone()));
            if m.channel.topic == "/detections" {
                assert_eq!(from_cdr::<Detection3DArray>(&m.data).unwrap(), d3);
                assert_eq!(m.publish_time, 3_000_000_007);
            }
        }
        assert_eq!(
            seen,
            [
                ("/detections".to_string(), DETECTION_3D_ARRAY.to_string()),
                ("/detections_2d".to_string(), DETECTION_2D_ARRAY.to_string())
            ]
        );
    }
}
