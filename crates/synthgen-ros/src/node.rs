//! A ROS 2 node with no ROS installation: `ros2-client` over RustDDS (pure Rust DDS/RTPS,
//! interoperable with Fast DDS and Cyclone DDS, the RMWs of Humble and Jazzy). The node
//! subscribes a colour image, optionally a registered depth image, and the camera info, and
//! publishes `vision_msgs/Detection3DArray` and `Detection2DArray`; what it does with the
//! frames is the caller's (synthgen-jobs' `ros` runs the predictor).
//!
//! Topic names resolve as in ROS 2: an absolute name (`/camera/color/image_raw`) as is, a
//! relative one (`detections`) under the node's namespace. QoS: the subscriptions use ROS 2's
//! sensor-data profile (best effort, keep last 5, volatile: they match both reliable and
//! best-effort camera drivers), the publishers ROS 2's default (reliable, keep last 10,
//! volatile).

use std::time::Duration;

use ros2_client::qos::{Durability, History, QosProfile, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
    Subscription,
};

use crate::msgs::{CameraInfo, Detection2DArray, Detection3DArray, Image};

/// Where the node lives and what it reads and writes.
#[derive(Debug, Clone)]
pub struct NodeConfig {
    /// DDS domain (ROS_DOMAIN_ID).
    pub domain_id: u16,
    /// The node's namespace (`/` or `/robot1`).
    pub namespace: String,
    pub name: String,
    /// `sensor_msgs/Image` colour topic (rgb8, bgr8, rgba8, bgra8, mono8).
    pub image_topic: String,
    /// `sensor_msgs/Image` depth registered to the colour (16UC1 mm, 32FC1 m).
    pub depth_topic: Option<String>,
    /// `sensor_msgs/CameraInfo` of the colour camera.
    pub camera_info_topic: String,
    /// `vision_msgs/Detection3DArray` published.
    pub detections_topic: String,
    /// `vision_msgs/Detection2DArray` published.
    pub detections_2d_topic: String,
}

/// The node: its subscriptions and publishers.
pub struct PoseNode {
    // Dropped after the entities it made (fields drop in order).
    image: Subscription<Image>,
    depth: Option<Subscription<Image>>,
    info: Subscription<CameraInfo>,
    out_3d: Publisher<Detection3DArray>,
    out_2d: Publisher<Detection2DArray>,
    node: Node,
    _context: Context,
    /// The topics' fully qualified names, as a ROS user lists them (`ros2 topic list`).
    pub topics: Topics,
}

/// The node's topics, fully qualified.
#[derive(Debug, Clone)]
pub struct Topics {
    pub image: String,
    pub depth: Option<String>,
    pub camera_info: String,
    pub detections: String,
    pub detections_2d: String,
}

/// ROS 2's `rmw_qos_profile_sensor_data`.
pub fn sensor_data_qos() -> QosProfile {
    QosProfile::subscription_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 5 })
}

/// ROS 2's default publisher profile.
pub fn default_qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(Duration::from_millis(100)))
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 10 })
}

/// A message taken from a subscription, or why one could not be read (logged and skipped).
pub type Taken<T> = Result<Option<T>, String>;

fn resolve(namespace: &str, topic: &str) -> String {
    if topic.starts_with('/') {
        topic.to_string()
    } else if namespace == "/" {
        format!("/{topic}")
    } else {
        format!("{}/{topic}", namespace.trim_end_matches('/'))
    }
}

impl PoseNode {
    /// Joins the DDS domain and creates the node's subscriptions and publishers.
    pub fn new(cfg: &NodeConfig) -> Result<PoseNode, String> {
        let context = Context::with_options(ContextOptions::new().domain_id(cfg.domain_id))
            .map_err(|e| format!("cannot join DDS domain {}: {e:?}", cfg.domain_id))?;
        let node_name = NodeName::new(&cfg.namespace, &cfg.name)
            .map_err(|e| format!("node {:?} in {:?}: {e:?}", cfg.name, cfg.namespace))?;
        let mut node = context
            .new_node(node_name, NodeOptions::new().enable_rosout(false))
            .map_err(|e| format!("cannot create the node: {e:?}"))?;
        let topics = Topics {
            image: resolve(&cfg.namespace, &cfg.image_topic),
            depth: cfg
                .depth_topic
                .as_deref()
                .map(|t| resolve(&cfg.namespace, t)),
            camera_info: resolve(&cfg.namespace, &cfg.camera_info_topic),
            detections: resolve(&cfg.namespace, &cfg.detections_topic),
            detections_2d: resolve(&cfg.namespace, &cfg.detections_2d_topic),
        };
        let sensor = sensor_data_qos();
        let default = default_qos();
        let topic = |node: &Node, name: &str, pkg: &str, ty: &str, qos: &QosProfile| {
            let n = Name::parse(name).map_err(|e| format!("topic {name:?}: {e:?}"))?;
            node.create_topic(&n, MessageTypeName::new(pkg, ty), qos)
                .map_err(|e| format!("topic {name}: {e:?}"))
        };
        let t = topic(&node, &topics.image, "sensor_msgs", "Image", &sensor)?;
        let image = node
            .create_subscription::<Image>(&t, Some(sensor.clone()))
            .map_err(|e| format!("subscribing {}: {e:?}", topics.image))?;
        let depth = match &topics.depth {
            Some(d) => {
                let t = topic(&node, d, "sensor_msgs", "Image", &sensor)?;
                Some(
                    node.create_subscription::<Image>(&t, Some(sensor.clone()))
                        .map_err(|e| format!("subscribing {d}: {e:?}"))?,
                )
            }
            None => None,
        };
        let t = topic(
            &node,
            &topics.camera_info,
            "sensor_msgs",
            "CameraInfo",
            &sensor,
        )?;
        let info = node
            .create_subscription::<CameraInfo>(&t, Some(sensor.clone()))
            .map_err(|e| format!("subscribing {}: {e:?}", topics.camera_info))?;
        let t = topic(
            &node,
            &topics.detections,
            "vision_msgs",
            "Detection3DArray",
            &default,
        )?;
        let out_3d = node
            .create_publisher::<Detection3DArray>(&t, Some(default.clone()))
            .map_err(|e| format!("publishing {}: {e:?}", topics.detections))?;
        let t = topic(
            &node,
            &topics.detections_2d,
            "vision_msgs",
            "Detection2DArray",
            &default,
        )?;
        let out_2d = node
            .create_publisher::<Detection2DArray>(&t, Some(default.clone()))
            .map_err(|e| format!("publishing {}: {e:?}", topics.detections_2d))?;
        Ok(PoseNode {
            image,
            depth,
            info,
            out_3d,
            out_2d,
            node,
            _context: context,
            topics,
        })
    }

    /// The next colour image received, if any.
    pub fn take_image(&self) -> Taken<Image> {
        take(&self.image)
    }

    /// The next depth image received, if any (None without a depth topic).
    pub fn take_depth(&self) -> Taken<Image> {
        match &self.depth {
            Some(s) => take(s),
            None => Ok(None),
        }
    }

    /// The next camera info received, if any.
    pub fn take_camera_info(&self) -> Taken<CameraInfo> {
        take(&self.info)
    }

    /// Publishes one frame's detections.
    pub fn publish(&self, d3: Detection3DArray, d2: Detection2DArray) -> Result<(), String> {
        self.out_3d
            .publish(d3)
            .map_err(|e| format!("publishing on {}: {e:?}", self.topics.detections))?;
        self.out_2d
            .publish(d2)
            .map_err(|e| format!("publishing on {}: {e:?}", self.topics.detections_2d))
    }

    /// How many subscriptions of other participants match the detections topic.
    pub fn detection_subscribers(&self) -> usize {
        self.out_3d.get_subscription_count(&self.node)
    }
}

fn take<T: 'static + serde::de::DeserializeOwned>(s: &Subscription<T>) -> Taken<T> {
    match s.take() {
        Ok(m) => Ok(m.map(|(m, _)| m)),
        Err(e) => Err(format!("{e:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::resolve;

    #[test]
    fn topic_names_resolve_as_in_ros() {
        assert_eq!(resolve("/", "detections"), "/detections");
        assert_eq!(resolve("/robot1", "detections"), "/robot1/detections");
        assert_eq!(resolve("/robot1/", "x/y"), "/robot1/x/y");
        assert_eq!(resolve("/robot1", "/camera/image"), "/camera/image");
    }
}
