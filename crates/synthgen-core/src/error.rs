use std::path::PathBuf;

/// Errors from core types: scene specs, cameras, poses.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot read scene spec: {source}: {path}")]
    ReadSpec {
        source: std::io::Error,
        path: PathBuf,
    },
    #[error("malformed scene spec: {message}: {path}")]
    ParseSpec { message: String, path: PathBuf },
    #[error("invalid scene spec: {0}")]
    InvalidSpec(String),
    #[error("cannot read sensor file: {source}: {path}")]
    ReadSensor {
        source: std::io::Error,
        path: PathBuf,
    },
    #[error("malformed sensor file: {message}: {path}")]
    ParseSensor { message: String, path: PathBuf },
    #[error("invalid sensor file: {message}: {path}")]
    InvalidSensor { message: String, path: PathBuf },
    #[error(
        "unknown sensor {0:?}: neither a sensor file nor one of none, d455, tof, structured_light"
    )]
    UnknownSensor(String),
    #[error("unknown camera preset {0:?} (known: linemod, d455, d455-720, ycbv, ycbv-cmu)")]
    UnknownCamera(String),
    #[error("invalid pose: {0}")]
    InvalidPose(String),
    #[error("cannot place {name} without interpenetration after {tries} tries (placement area {area_m:?} m); enlarge [placement] area_m or use fewer objects")]
    Placement {
        name: String,
        tries: u32,
        area_m: [f64; 2],
    },
    #[error("no view of frame {frame} in {tries} tries has {what}; lower camera.min_visib_fract, set camera.allow_truncation = true, or raise camera.max_view_tries")]
    View {
        frame: u64,
        tries: u32,
        what: String,
    },
    #[error("view check failed: {0}")]
    ViewCheck(String),
}
