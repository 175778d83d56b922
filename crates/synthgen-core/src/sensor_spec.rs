//! The `[sensor]` section of a scene spec: which depth-sensor model and which RGB noise to
//! apply to a rendered frame (after the annotations are computed from the clean render).
//! The models themselves live in `synthgen_render::sensor`; docs/sensors.md gives the
//! formulas and their sources.

use serde::{Deserialize, Serialize};

use crate::range::Range;
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
    /// Structured light, the Kinect v1 / PrimeSense / Asus Xtion family (see
    /// `StructuredLightSpec`).
    StructuredLight,
}

#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorSpec {
    /// A sensor file (`synthgen sensor fit` writes them; `sensors/` holds the shipped ones)
    /// whose contents stand for this section; relative to the scene file. Only `rgb` may be
    /// given beside it (it then replaces the file's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<std::path::PathBuf>,
    /// `none` (default), `d455`, `tof` or `structured_light`.
    pub depth: DepthModel,
    pub d455: D455Spec,
    pub tof: TofSpec,
    pub structured_light: StructuredLightSpec,
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

/// Structured-light depth (Kinect v1 / PrimeSense / Asus Xtion): a projector beside the
/// depth camera, depth from the disparity of the projected pattern. In order, all from the
/// clean render: a closer surface spreads `fattening_px` over a farther one at its edges;
/// pixels the projector cannot light (the shadow beside every object, on the side away from
/// the projector) are holes; near a depth edge a pixel reads the far side's depth
/// (`edge_mix`) or nothing (`edge_dropout`), both decaying as exp(−d / `edge_width_px`) with
/// the distance d to the edge; holes at grazing incidence, on dark and on bright (specular
/// highlight) surfaces, and at random (`dropout`); the rest get disparity noise, disparity
/// quantization and a bias: z = f b / round(f b / z + σ_d n, `subpixel`) + `bias_m`; last,
/// the whole image is displaced by `shift_px` (registration error). Every
/// parameter here can be fitted to real frames with `synthgen sensor fit` (docs/sensors.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StructuredLightSpec {
    /// Projector position along the camera's x axis, metres, signed: negative = the projector
    /// sits left of the camera and the shadows fall on the right of objects, positive = the
    /// reverse. |baseline_m| sets the shadow width f |b| (1/z_near − 1/z_far) pixels and the
    /// depth resolution. Default −0.075 (PrimeSense).
    pub baseline_m: f64,
    /// A second viewpoint whose occlusions are holes too, metres along x, signed (0 = none):
    /// the depth camera itself when its image is registered to a colour camera beside it, so
    /// a thinner shadow falls on the other side. Default 0.
    pub second_view_m: f64,
    /// Focal length of the disparity (IR) image, pixels; 0 = the rendered camera's fx.
    /// Default 0.
    pub focal_px: f64,
    /// Disparity quantization step, pixels at `focal_px` (PrimeSense: 1/8); 0 = none.
    /// Default 0.125.
    pub subpixel: f64,
    /// Disparity noise σ_d, pixels at `focal_px`: σ_z ≈ z² σ_d / (f |b|). Default 0.1.
    pub disparity_sigma_px: f64,
    /// Lateral (in-image) noise of the pattern's position, pixels: on a surface seen at
    /// incidence θ it moves the reading by σ_lat · z / fx · tan θ. Default 0.3.
    pub lateral_sigma_px: f64,
    /// Constant added to every reading, metres. Default 0.
    pub bias_m: f64,
    /// Readings outside this range are 0 (invalid), metres. Default 0.4..8.0.
    pub range_m: Range,
    /// Pixels the projector cannot light are holes. Default true.
    pub shadow: bool,
    /// A pixel is on a depth edge when a 4-neighbour is empty or differs by more than this
    /// fraction of its depth. Default 0.03.
    pub edge_jump_rel: f64,
    /// Hole probability on a depth edge (d = 0), decaying as exp(−d / `edge_width_px`).
    /// Default 0.3.
    pub edge_dropout: f64,
    /// Decay length of the edge effects, pixels. Default 2.0.
    pub edge_width_px: f64,
    /// Probability (same decay) that a pixel near an edge reads the farthest surface within
    /// d + 1 pixels (a hole when that is empty). Default 0.1.
    pub edge_mix: f64,
    /// How far a closer surface spreads over a farther one at its edges, pixels (fractional:
    /// the last pixel with that probability). Default 0.5.
    pub fattening_px: f64,
    /// The depth image is displaced this many pixels along x against the colour image and the
    /// masks (a depth-to-colour registration error; negative = to the left; fractional: each
    /// pixel reads one of the two nearest columns, the farther with the fraction's
    /// probability). Default 0.
    pub shift_px: f64,
    /// Incidence angle at which half of the pixels are holes, degrees. Default 78.
    pub grazing_deg: f64,
    /// Width of that logistic step, degrees. Default 4.
    pub grazing_width_deg: f64,
    /// Below this brightness (0..1, of the rendered colour) holes ramp up linearly to
    /// `dark_dropout` at black. Default 0.1.
    pub dark_luminance: f64,
    /// Hole probability on black. Default 0.1.
    pub dark_dropout: f64,
    /// Above this brightness holes ramp up linearly to `bright_dropout` at white (specular
    /// highlights saturate the IR pattern). Default 0.8.
    pub bright_luminance: f64,
    /// Hole probability on white. Default 0.2.
    pub bright_dropout: f64,
    /// Hole probability of any other pixel. Default 0.01.
    pub dropout: f64,
    /// Holes come in blobs about this many pixels wide: the hole, edge-mixing and shift
    /// decisions read a smooth random field with this correlation length instead of
    /// independent draws (≤ 1: independent pixels). Default 3.
    pub hole_size_px: f64,
    /// Output rounding, metres (0 = none). Default 0.001 (OpenNI's millimetres).
    pub depth_unit_m: f64,
}

impl Default for StructuredLightSpec {
    fn default() -> Self {
        Self {
            baseline_m: -0.075,
            second_view_m: 0.0,
            focal_px: 0.0,
            subpixel: 0.125,
            disparity_sigma_px: 0.1,
            lateral_sigma_px: 0.3,
            bias_m: 0.0,
            range_m: [0.4, 8.0],
            shadow: true,
            edge_jump_rel: 0.03,
            edge_dropout: 0.3,
            edge_width_px: 2.0,
            edge_mix: 0.1,
            fattening_px: 0.5,
            shift_px: 0.0,
            grazing_deg: 78.0,
            grazing_width_deg: 4.0,
            dark_luminance: 0.1,
            dark_dropout: 0.1,
            bright_luminance: 0.8,
            bright_dropout: 0.2,
            dropout: 0.01,
            hole_size_px: 3.0,
            depth_unit_m: 0.001,
        }
    }
}

impl StructuredLightSpec {
    /// Hole probability (before shadow, range and edge mixing) at distance `edge_px` from a
    /// depth edge, incidence `incidence_deg` and brightness `luminance`: independent causes,
    /// 1 − Π (1 − p_k).
    pub fn hole_probability(&self, edge_px: f64, incidence_deg: f64, luminance: f64) -> f64 {
        let edge = self.edge_dropout * (-edge_px / self.edge_width_px.max(1e-6)).exp();
        let graze = 1.0
            / (1.0
                + (-(incidence_deg - self.grazing_deg) / self.grazing_width_deg.max(1e-6)).exp());
        1.0 - self.keep_by_brightness(luminance) * (1.0 - edge) * (1.0 - graze)
    }

    /// The probability that a pixel of brightness `luminance` (0..1) keeps its reading as far
    /// as the dark, bright and random holes go: (1 − dropout)(1 − p_dark)(1 − p_bright).
    pub fn keep_by_brightness(&self, luminance: f64) -> f64 {
        let dark = if luminance < self.dark_luminance {
            self.dark_dropout * (self.dark_luminance - luminance) / self.dark_luminance.max(1e-6)
        } else {
            0.0
        };
        let bright = if luminance > self.bright_luminance {
            self.bright_dropout * (luminance - self.bright_luminance)
                / (1.0 - self.bright_luminance).max(1e-6)
        } else {
            0.0
        };
        (1.0 - self.dropout) * (1.0 - dark) * (1.0 - bright)
    }

    /// Probability that a pixel `edge_px` from a depth edge reads the far side.
    pub fn mix_probability(&self, edge_px: f64) -> f64 {
        self.edge_mix * (-edge_px / self.edge_width_px.max(1e-6)).exp()
    }

    /// f |b| in pixel·metres with the disparity focal length (`focal_px`, else `camera_fx`).
    pub fn focal_baseline(&self, camera_fx: f64) -> f64 {
        let f = if self.focal_px > 0.0 {
            self.focal_px
        } else {
            camera_fx
        };
        f * self.baseline_m.abs()
    }

    /// The depth step of the disparity quantization at depth `z_m`: z² · subpixel / (f |b|).
    pub fn depth_step_m(&self, z_m: f64, camera_fx: f64) -> f64 {
        z_m * z_m * self.subpixel / self.focal_baseline(camera_fx)
    }

    /// The noise σ at depth `z_m` and incidence `incidence_deg`, metres: the disparity noise
    /// z² σ_d / (f |b|) and the lateral term σ_lat z / fx · tan θ (θ capped at 85°), added in
    /// quadrature (quantization not included).
    pub fn sigma_m(&self, z_m: f64, incidence_deg: f64, camera_fx: f64) -> f64 {
        let axial = z_m * z_m * self.disparity_sigma_px / self.focal_baseline(camera_fx);
        let lateral =
            self.lateral_sigma_px * z_m / camera_fx * incidence_deg.min(85.0).to_radians().tan();
        axial.hypot(lateral)
    }

    fn validate(&self) -> Result<(), Error> {
        let s = self;
        let b = s.baseline_m.abs();
        if !(s.baseline_m.is_finite() && (1e-3..=10.0).contains(&b)) {
            return Err(Error::InvalidSpec(format!(
                "sensor.structured_light.baseline_m must be ±0.001..10 m (its sign sets the shadow side), got {}",
                s.baseline_m
            )));
        }
        let p = "sensor.structured_light";
        check_value(&format!("{p}.focal_px"), s.focal_px, 0.0, 1e5)?;
        check_value(&format!("{p}.subpixel"), s.subpixel, 0.0, 10.0)?;
        check_value(
            &format!("{p}.disparity_sigma_px"),
            s.disparity_sigma_px,
            0.0,
            100.0,
        )?;
        check_value(&format!("{p}.second_view_m"), s.second_view_m, -10.0, 10.0)?;
        check_value(
            &format!("{p}.lateral_sigma_px"),
            s.lateral_sigma_px,
            0.0,
            100.0,
        )?;
        check_value(&format!("{p}.bias_m"), s.bias_m, -1.0, 1.0)?;
        check_range(&format!("{p}.range_m"), s.range_m, 0.0)?;
        check_value(&format!("{p}.edge_jump_rel"), s.edge_jump_rel, 0.0, 100.0)?;
        check_value(&format!("{p}.edge_dropout"), s.edge_dropout, 0.0, 1.0)?;
        check_value(&format!("{p}.edge_width_px"), s.edge_width_px, 0.1, 50.0)?;
        check_value(&format!("{p}.edge_mix"), s.edge_mix, 0.0, 1.0)?;
        check_value(&format!("{p}.fattening_px"), s.fattening_px, 0.0, 20.0)?;
        check_value(&format!("{p}.shift_px"), s.shift_px, -20.0, 20.0)?;
        check_value(&format!("{p}.grazing_deg"), s.grazing_deg, 0.0, 180.0)?;
        check_value(
            &format!("{p}.grazing_width_deg"),
            s.grazing_width_deg,
            0.01,
            90.0,
        )?;
        check_value(&format!("{p}.dark_luminance"), s.dark_luminance, 0.0, 1.0)?;
        check_value(&format!("{p}.dark_dropout"), s.dark_dropout, 0.0, 1.0)?;
        check_value(
            &format!("{p}.bright_luminance"),
            s.bright_luminance,
            0.0,
            1.0,
        )?;
        check_value(&format!("{p}.bright_dropout"), s.bright_dropout, 0.0, 1.0)?;
        check_value(&format!("{p}.dropout"), s.dropout, 0.0, 1.0)?;
        check_value(&format!("{p}.hole_size_px"), s.hole_size_px, 0.0, 64.0)?;
        check_value(&format!("{p}.depth_unit_m"), s.depth_unit_m, 0.0, 1.0)?;
        Ok(())
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
    /// White balance error per frame: the red and blue gains are drawn uniformly in
    /// 1 ± this, relative to green. Default 0 (none).
    pub white_balance: f64,
    /// Vignetting per frame: the image darkens by `k · r²` towards the corners (r = 1 at the
    /// half diagonal), k uniform in this range. Default [0, 0] (none).
    pub vignetting: Range,
    /// Defocus per frame: the blur radius, pixels, of a point at infinity (a thin lens's
    /// circle of confusion c(z) = this × |1 − z_f / z|), uniform in this range; the focus
    /// distance z_f is the median depth of the frame's object pixels (autofocus on the
    /// objects). Default [0, 0] (none).
    pub defocus_px: Range,
    /// Motion blur per frame: a streak of this length, pixels, uniform in this range, in a
    /// direction drawn uniformly (camera shake). Default [0, 0] (none).
    pub motion_blur_px: Range,
    /// JPEG compression per frame: the quality 1..100 uniform in this range (a camera or a
    /// recording that stores compressed frames). Default [0, 0] (none).
    pub jpeg_quality: Range,
}

impl Default for RgbNoiseSpec {
    fn default() -> Self {
        Self {
            enabled: false,
            exposure_stops: [-0.3, 0.3],
            blur_sigma_px: [0.0, 0.7],
            shot_noise: 0.0004,
            read_noise: 0.003,
            white_balance: 0.0,
            vignetting: [0.0, 0.0],
            defocus_px: [0.0, 0.0],
            motion_blur_px: [0.0, 0.0],
            jpeg_quality: [0.0, 0.0],
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
    /// The model sections set (unlike their defaults) beside a `depth` that does not use them,
    /// as messages: `depth = "none"` with a `[structured_light]` section renders clean depth,
    /// which the user who wrote the section likely did not mean.
    pub fn unused_sections(&self) -> Vec<String> {
        let set = [
            ("d455", DepthModel::D455, self.d455 != D455Spec::default()),
            ("tof", DepthModel::Tof, self.tof != TofSpec::default()),
            (
                "structured_light",
                DepthModel::StructuredLight,
                self.structured_light != StructuredLightSpec::default(),
            ),
        ];
        let depth = match self.depth {
            DepthModel::None => "none",
            DepthModel::D455 => "d455",
            DepthModel::Tof => "tof",
            DepthModel::StructuredLight => "structured_light",
        };
        let mut out: Vec<String> = set
            .into_iter()
            .filter(|&(_, model, differs)| differs && model != self.depth)
            .map(|(name, _, _)| {
                format!(
                    "sensor.{name} is set but sensor.depth is \"{depth}\": it has no effect (set depth = \"{name}\" to use it)"
                )
            })
            .collect();
        let rgb_set = RgbNoiseSpec {
            enabled: false,
            ..self.rgb.clone()
        } != RgbNoiseSpec::default();
        if !self.rgb.enabled && rgb_set {
            out.push(
                "sensor.rgb is set but sensor.rgb.enabled is false: its effects are not applied (set enabled = true to use them)"
                    .into(),
            );
        }
        out
    }

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
        self.structured_light.validate()?;
        let r = &self.rgb;
        check_range("sensor.rgb.exposure_stops", r.exposure_stops, -10.0)?;
        check_range("sensor.rgb.blur_sigma_px", r.blur_sigma_px, 0.0)?;
        check_value("sensor.rgb.blur_sigma_px", r.blur_sigma_px[1], 0.0, 10.0)?;
        check_value("sensor.rgb.shot_noise", r.shot_noise, 0.0, 1.0)?;
        check_value("sensor.rgb.read_noise", r.read_noise, 0.0, 1.0)?;
        check_value("sensor.rgb.white_balance", r.white_balance, 0.0, 0.5)?;
        check_range("sensor.rgb.vignetting", r.vignetting, 0.0)?;
        check_value("sensor.rgb.vignetting", r.vignetting[1], 0.0, 1.0)?;
        check_range("sensor.rgb.defocus_px", r.defocus_px, 0.0)?;
        check_value("sensor.rgb.defocus_px", r.defocus_px[1], 0.0, 30.0)?;
        check_range("sensor.rgb.motion_blur_px", r.motion_blur_px, 0.0)?;
        check_value("sensor.rgb.motion_blur_px", r.motion_blur_px[1], 0.0, 40.0)?;
        check_range("sensor.rgb.jpeg_quality", r.jpeg_quality, 0.0)?;
        check_value("sensor.rgb.jpeg_quality", r.jpeg_quality[1], 0.0, 100.0)?;
        // A quality is 1..100 (JPEG's scale, not a fraction); [0, 0] is no compression.
        if r.jpeg_quality[1] > 0.0 && r.jpeg_quality[0] < 1.0 {
            return Err(Error::InvalidSpec(format!(
                "sensor.rgb.jpeg_quality is a JPEG quality from 1 to 100 (not a fraction), or [0, 0] for none; got [{}, {}]",
                r.jpeg_quality[0], r.jpeg_quality[1]
            )));
        }
        Ok(())
    }

    /// True when the sensor changes nothing.
    pub fn is_identity(&self) -> bool {
        self.depth == DepthModel::None && !self.rgb.enabled
    }

    /// A sensor by name: `none`, `d455`, `tof` or `structured_light` (each with its
    /// defaults), or `None` for any other name.
    pub fn builtin(name: &str) -> Option<SensorSpec> {
        let depth = match name.to_ascii_lowercase().replace('-', "_").as_str() {
            "none" => DepthModel::None,
            "d455" => DepthModel::D455,
            "tof" => DepthModel::Tof,
            "structured_light" => DepthModel::StructuredLight,
            _ => return None,
        };
        Some(SensorSpec {
            depth,
            ..SensorSpec::default()
        })
    }

    /// Parses a sensor file: the keys of a scene's `[sensor]` section at the top level
    /// (`depth = "structured_light"`, `[structured_light]`, `[rgb]`, ...), checked.
    pub fn from_toml_str(text: &str) -> Result<SensorSpec, Error> {
        let spec: SensorSpec = toml::from_str(text).map_err(|e| Error::ParseSpec {
            message: e.to_string().trim().replace('\n', " "),
            path: std::path::PathBuf::from("<string>"),
        })?;
        if spec.file.is_some() {
            return Err(Error::InvalidSpec(
                "a sensor file cannot name another sensor file (`file`)".into(),
            ));
        }
        let given: toml::Value = toml::from_str(text).map_err(|e| Error::ParseSpec {
            message: e.to_string(),
            path: std::path::PathBuf::from("<string>"),
        })?;
        let kept = toml::Value::try_from(&spec).map_err(|e| Error::ParseSpec {
            message: e.to_string(),
            path: std::path::PathBuf::from("<string>"),
        })?;
        crate::range::check_nothing_dropped(&given, &kept, "sensor")?;
        spec.validate()?;
        Ok(spec)
    }

    /// Reads a sensor file ([`from_toml_str`](Self::from_toml_str)); errors name the file.
    pub fn from_toml_file(path: &std::path::Path) -> Result<SensorSpec, Error> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::ReadSensor {
            source,
            path: path.to_path_buf(),
        })?;
        Self::from_toml_str(&text).map_err(|e| match e {
            Error::ParseSpec { message, .. } => Error::ParseSensor {
                message,
                path: path.to_path_buf(),
            },
            Error::InvalidSpec(message) => Error::InvalidSensor {
                message,
                path: path.to_path_buf(),
            },
            other => other,
        })
    }

    /// A `--sensor` value: `none`, `d455`, `tof`, `structured_light`, or a sensor file.
    pub fn from_name_or_file(arg: &str) -> Result<SensorSpec, Error> {
        if let Some(s) = Self::builtin(arg) {
            return Ok(s);
        }
        let path = std::path::Path::new(arg);
        if !path.exists() {
            return Err(Error::UnknownSensor(arg.to_string()));
        }
        Self::from_toml_file(path)
    }

    /// The file's text: what `synthgen sensor fit` writes, readable by
    /// [`from_toml_str`](Self::from_toml_str).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// Replaces a `file = ...` section with that file's contents (`base`: the folder the
    /// path is relative to); `rgb` given beside `file` wins over the file's.
    pub fn resolve_file(&mut self, base: &std::path::Path) -> Result<(), Error> {
        let Some(file) = self.file.take() else {
            return Ok(());
        };
        let path = if file.is_relative() {
            base.join(&file)
        } else {
            file.clone()
        };
        let rest = SensorSpec {
            rgb: RgbNoiseSpec::default(),
            ..self.clone()
        };
        if rest != SensorSpec::default() {
            return Err(Error::InvalidSpec(format!(
                "sensor.file = {:?}: give either the file or the sensor's keys (only `rgb` may sit beside `file`)",
                file.display()
            )));
        }
        let mut loaded = Self::from_toml_file(&path)?;
        if self.rgb != RgbNoiseSpec::default() {
            loaded.rgb = self.rgb.clone();
        }
        *self = loaded;
        Ok(())
    }
}
