//! ROS 2 for synthgen, with no ROS installation: [`rosbag`] reads (and writes) the camera
//! messages of ROS 2 bags in MCAP, which `synthgen predict --bag` runs the models on.

pub mod rosbag;
