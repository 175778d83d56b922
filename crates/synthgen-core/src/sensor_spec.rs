//! The `[sensor]` section of a scene spec: which depth-sensor model and which RGB noise to
//! apply to a rendered frame (after the annotations are computed from the clean render).
//! The models themselves live in `synthgen_render::sensor`; docs/sensors.md gives the
//! formulas and their sources.

use serde::{Deserialize, Serialize};

use crate::scene::Range;
use crate::Error;

/// Depth-sensor model applied to the rendered depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthModel {
    /// The clean rendered depth (default).
    #[default]
    None,
    /// Intel RealSense D455-style active stereo (see `D455Spec`).
    D455,
    /// Kinect / time-of-flight style (see `TofSpec`).
    Tof,
}

#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorSpec {
    /// `none` (default), `d455` or `tof`.
    pub depth: DepthModel,
    pub d455: D455Spec,
    pub tof: TofSpec,
    pub rgb: RgbNoiseSpec,
}

/// Stereo depth: σ_z = z² σ_d / (f b), with f = the camera's fx in pixels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct D455Spec {
    /// Stereo baseline b, metres. Default 0.095 (D455).
    pub baseline_m: f64,
    /// Sub-pixel disparity noise σ_d, pixels. Default 0.08.
    pub subpixel_sigma_px: f64,
    /// Depth outside this range is 0 (invalid), metres. Default 0.6..6.0.
    pub range_m: Range,
    /// Output depth is rounded to a multiple of this, metres (the D4xx depth unit). Default
    /// 0.001; 0 disables quantization.
    pub depth_unit_m: f64,
    /// Pixels occluded from the second imager (at +baseline along x) are 0. Default true.
    pub stereo_shadow: bool,
    /// A pixel is on a depth discontinuity when a 4-neighbour's depth differs by more than
    /// this fraction of its own depth. Default 0.04.
    pub edge_jump_rel: f64,
    /// Probability that a discontinuity pixel becomes a hole (0). Default 0.6.
    pub edge_dropout: f64,
    /// Probability that any other valid pixel becomes a hole. Default 0.002.
    pub dropout: f64,
}

impl Default for D455Spec {
    fn default() -> Self {
        Self {
            baseline_m: 0.095,
            subpixel_sigma_px: 0.08,
            range_m: [0.6, 6.0],
            depth_unit_m: 0.001,
            stereo_shadow: true,
            edge_jump_rel: 0.04,
            edge_dropout: 0.6,
            dropout: 0.002,
        }
    }
}

/// Kinect / time-of-flight style depth. Axial noise after Nguyen et al. (2012):
/// σ_z = a + b (z − z0)² + c / √z · θ² / (π/2 − θ)², θ = angle of incidence; lateral
/// noise as a pixel jitter; flying pixels (a mix of foreground and background) at edges.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TofSpec {
    /// Constant axial noise a, metres. Default 0.0012.
    pub sigma_a_m: f64,
    /// Quadratic axial term b, 1/metre. Default 0.0019.
    pub sigma_b_per_m: f64,
    /// Depth z0 where the quadratic term vanishes, metres. Default 0.4.
    pub sigma_z0_m: f64,
    /// Incidence-angle term c, metres^1.5. Default 0.0001.
    pub sigma_angle_m: f64,
    /// Incidence angles above this are invalid (0), degrees. Default 80.
    pub max_incidence_deg: f64,
    /// Depth outside this range is 0 (invalid), metres. Default 0.4..4.0.
    pub range_m: Range,
    /// Probability that a pixel on a depth discontinuity becomes a flying pixel: its depth is
    /// a uniform mix of the nearest and farthest depth among its 4-neighbours. Default 0.5.
    pub flying_pixel_prob: f64,
    /// A pixel is on a discontinuity when a 4-neighbour differs by more than this fraction
    /// of its depth. Default 0.04.
    pub edge_jump_rel: f64,
    /// Lateral noise: probability that a pixel takes a random 4-neighbour's depth. Default 0.1.
    pub lateral_jitter: f64,
    /// Output rounding, metres (0 = none). Default 0.001.
    pub depth_unit_m: f64,
}

impl Default for TofSpec {
    fn default() -> Self {
        Self {
            sigma_a_m: 0.0012,
            sigma_b_per_m: 0.0019,
            sigma_z0_m: 0.4,
            sigma_angle_m: 0.0001,
            max_incidence_deg: 80.0,
            range_m: [0.4, 4.0],
            flying_pixel_prob: 0.5,
            edge_jump_rel: 0.04,
            lateral_jitter: 0.1,
            depth_unit_m: 0.001,
        }
    }
}

/// RGB sensor effects, in linear light: exposure, blur, then shot + read noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RgbNoiseSpec {
    /// Apply the RGB effects. Default false.
    pub enabled: bool,
    /// Exposure change per frame, stops (×2^s). Default -0.3..0.3.
    pub exposure_stops: Range,
    /// Gaussian blur σ per frame, pixels (0 = none). Default 0.0..0.7.
    pub blur_sigma_px: Range,
    /// Shot noise: variance = `shot_noise` × signal (signal in 0..1 linear). Default 0.0004.
    pub shot_noise: f64,
    /// Read noise σ, linear units. Default 0.003.
    pub read_noise: f64,
}

impl Default for RgbNoiseSpec {
    fn default() -> Self {
        Self {
            enabled: false,
            exposure_stops: [-0.3, 0.3],
            blur_sigma_px: [0.0, 0.7],
            shot_noise: 0.0004,
            read_noise: 0.003,
        }
    }
}

fn check_range(name: &str, [lo, hi]: Range, min: f64) -> Result<(), Error> {
    if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= min) {
        return Err(Error::InvalidSpec(format!(
            "{name} must be finite with {min} <= min <= max, got [{lo}, {hi}]"
        )));
    }
    Ok(())
}

fn check_value(name: &str, v: f64, lo: f64, hi: f64) -> Result<(), Error> {
    if !(v.is_finite() && v >= lo && v <= hi) {
        return Err(Error::InvalidSpec(format!(
            "{name} must lie within {lo}..{hi}, got {v}"
        )));
    }
    Ok(())
}

impl SensorSpec {
    /// Checks every parameter; errors name the field.
    pub fn validate(&self) -> Result<(), Error> {
        let d = &self.d455;
        check_value("sensor.d455.baseline_m", d.baseline_m, 1e-4, 10.0)?;
        check_value(
            "sensor.d455.subpixel_sigma_px",
            d.subpixel_sigma_px,
            0.0,
            100.0,
        )?;
        check_range("sensor.d455.range_m", d.range_m, 0.0)?;
        check_value("sensor.d455.depth_unit_m", d.depth_unit_m, 0.0, 1.0)?;
        check_value("sensor.d455.edge_jump_rel", d.edge_jump_rel, 0.0, 100.0)?;
        check_value("sensor.d455.edge_dropout", d.edge_dropout, 0.0, 1.0)?;
        check_value("sensor.d455.dropout", d.dropout, 0.0, 1.0)?;
        let t = &self.tof;
        check_value("sensor.tof.sigma_a_m", t.sigma_a_m, 0.0, 1.0)?;
        check_value("sensor.tof.sigma_b_per_m", t.sigma_b_per_m, 0.0, 1.0)?;
        check_value("sensor.tof.sigma_z0_m", t.sigma_z0_m, 0.0, 100.0)?;
        check_value("sensor.tof.sigma_angle_m", t.sigma_angle_m, 0.0, 1.0)?;
        check_value(
            "sensor.tof.max_incidence_deg",
            t.max_incidence_deg,
            0.0,
            89.9,
        )?;
        check_range("sensor.tof.range_m", t.range_m, 0.0)?;
        check_value(
            "sensor.tof.flying_pixel_prob",
            t.flying_pixel_prob,
            0.0,
            1.0,
        )?;
        check_value("sensor.tof.edge_jump_rel", t.edge_jump_rel, 0.0, 100.0)?;
        check_value("sensor.tof.lateral_jitter", t.lateral_jitter, 0.0, 1.0)?;
        check_value("sensor.tof.depth_unit_m", t.depth_unit_m, 0.0, 1.0)?;
        let r = &self.rgb;
        check_range("sensor.rgb.exposure_stops", r.exposure_stops, -10.0)?;
        check_range("sensor.rgb.blur_sigma_px", r.blur_sigma_px, 0.0)?;
        check_value("sensor.rgb.blur_sigma_px", r.blur_sigma_px[1], 0.0, 10.0)?;
        check_value("sensor.rgb.shot_noise", r.shot_noise, 0.0, 1.0)?;
        check_value("sensor.rgb.read_noise", r.read_noise, 0.0, 1.0)?;
        Ok(())
    }

    /// True when the sensor changes nothing.
    pub fn is_identity(&self) -> bool {
        self.depth == DepthModel::None && !self.rgb.enabled
    }
}
