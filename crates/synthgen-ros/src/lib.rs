//! ROS 2 for synthgen, with no ROS installation: [`rosbag`] reads (and writes) the camera
//! messages of ROS 2 bags in MCAP, which `synthgen predict --bag` runs the models on;
//! [`node`] is a ROS 2 node over DDS (`ros2-client` on RustDDS) that `synthgen ros` runs;
//! [`msgs`] the messages it reads and publishes, and [`record`] the bag of what it published.

pub mod msgs;
pub mod node;
pub mod record;
pub mod rosbag;
