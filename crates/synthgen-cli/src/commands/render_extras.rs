//! The `--sensor` flag's sensor, for `synthgen render` and `render --replay`.

use anyhow::{Context, Result};
use synthgen_core::scene::{RgbNoiseSpec, SensorSpec};

/// The sensor of `--sensor NAME|FILE`, which replaces the scene's `sensor` section; the
/// scene's RGB noise stays when the flag's sensor leaves `rgb` at its defaults (a built-in
/// name, or a file without `[rgb]`).
pub fn sensor_flag(arg: &str, scene: &SensorSpec) -> Result<SensorSpec> {
    let mut sensor =
        SensorSpec::from_name_or_file(arg).with_context(|| format!("invalid --sensor {arg}"))?;
    if sensor.rgb == RgbNoiseSpec::default() {
        sensor.rgb = scene.rgb.clone();
    }
    Ok(sensor)
}
