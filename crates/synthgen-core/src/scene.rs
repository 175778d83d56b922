//! The scene spec: everything that is randomized per frame, with its ranges. Read from TOML
//! (`scenes/*.toml`), every field optional with the default documented here.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use crate::bin_spec::BinSpec;
use crate::camera::Intrinsics;
pub use crate::distractor_spec::{DistractorShape, DistractorSpec};
pub use crate::range::Range;
use crate::range::{check_nothing_dropped, check_range};
pub use crate::rest::UpAxis;
pub use crate::sensor_spec::{
    D455Spec, DepthModel, RgbNoiseSpec, SensorSpec, StructuredLightSpec, TofSpec,
};
pub use crate::walls_spec::WallSpec;
use crate::walls_spec::{check_colors, check_scale};
use crate::Error;

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneSpec {
    pub camera: CameraSpec,
    pub camera_pose: CameraPoseSpec,
    pub placement: PlacementSpec,
    pub ground: GroundSpec,
    pub lights: LightSpec,
    pub background: BackgroundSpec,
    pub materials: MaterialSpec,
    /// Sensor models applied after rendering (depth noise, RGB noise). Default: none.
    pub sensor: SensorSpec,
    /// Objects rendered around the targets that get no annotations. Default: none.
    pub distractors: DistractorSpec,
    /// Vertical textured planes around the scene (a square room). Default: none.
    pub walls: WallSpec,
    /// An open box around the placement area (physics and rendering). Default: none.
    pub bin: BinSpec,
    /// Objects declared in the spec (in addition to `--objects` on the command line).
    pub objects: Vec<ObjectSpec>,
}

/// Camera intrinsics: a preset name, optionally overridden field by field. A `width` and
/// `height` without any of `fx`, `fy`, `cx`, `cy` resize the preset (its intrinsics scaled:
/// the same camera at another resolution); with any of them given, the fields are used as
/// they are. The principal point must lie inside the image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraSpec {
    /// `linemod` (default), `d455`, `d455-720`, `ycbv` or `ycbv-cmu`.
    pub preset: String,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub fx: Option<f64>,
    pub fy: Option<f64>,
    pub cx: Option<f64>,
    pub cy: Option<f64>,
    /// A view is re-sampled when any target's visible fraction (BOP `visib_fract`, with the
    /// distractors and other targets as occluders) is below this, 0..1. Default 0 (off).
    pub min_visib_fract: f64,
    /// Views tried per frame before the frame fails. Default 50.
    pub max_view_tries: u32,
    /// Keep views where a target's silhouette leaves the image (BOP semantics: its
    /// `visib_fract` counts the pixels outside as not visible). Default true (the behaviour
    /// before this knob existed); false re-samples such views.
    pub allow_truncation: bool,
}

impl Default for CameraSpec {
    fn default() -> Self {
        Self {
            preset: "linemod".into(),
            width: None,
            height: None,
            fx: None,
            fy: None,
            cx: None,
            cy: None,
            min_visib_fract: 0.0,
            max_view_tries: 50,
            allow_truncation: true,
        }
    }
}

impl CameraSpec {
    /// Sets the image size, scaling the camera to it: the preset's intrinsics as
    /// [`intrinsics`](Self::intrinsics) scales them, and an explicit K (a scene file's
    /// `[camera]` fx, fy, cx, cy, given for the spec's current size) likewise, so that the
    /// same camera is rendered at another resolution.
    pub fn set_image_size(&mut self, width: u32, height: u32) -> Result<(), Error> {
        let explicit =
            self.fx.is_some() || self.fy.is_some() || self.cx.is_some() || self.cy.is_some();
        if explicit {
            let k = self.intrinsics()?;
            let (sx, sy) = (
                f64::from(width) / f64::from(k.width),
                f64::from(height) / f64::from(k.height),
            );
            self.fx = Some(k.fx * sx);
            self.fy = Some(k.fy * sy);
            self.cx = Some((k.cx + 0.5) * sx - 0.5);
            self.cy = Some((k.cy + 0.5) * sy - 0.5);
        }
        self.width = Some(width);
        self.height = Some(height);
        Ok(())
    }

    pub fn intrinsics(&self) -> Result<Intrinsics, Error> {
        let mut k = Intrinsics::preset(&self.preset)?;
        let explicit =
            self.fx.is_some() || self.fy.is_some() || self.cx.is_some() || self.cy.is_some();
        let (w, h) = (
            self.width.unwrap_or(k.width),
            self.height.unwrap_or(k.height),
        );
        if !explicit && (w, h) != (k.width, k.height) {
            // The preset at another resolution (pixel centres at integers: c' = (c + ½) s − ½).
            let (sx, sy) = (
                f64::from(w) / f64::from(k.width),
                f64::from(h) / f64::from(k.height),
            );
            k.fx *= sx;
            k.fy *= sy;
            k.cx = (k.cx + 0.5) * sx - 0.5;
            k.cy = (k.cy + 0.5) * sy - 0.5;
        }
        k.width = w;
        k.height = h;
        if let Some(v) = self.fx {
            k.fx = v;
        }
        if let Some(v) = self.fy {
            k.fy = v;
        }
        if let Some(v) = self.cx {
            k.cx = v;
        }
        if let Some(v) = self.cy {
            k.cy = v;
        }
        k.validate()?;
        if !(0.0..f64::from(k.width)).contains(&k.cx) || !(0.0..f64::from(k.height)).contains(&k.cy)
        {
            return Err(Error::InvalidSpec(format!(
                "the principal point ({}, {}) lies outside the {}x{} image: give cx and cy for this size (--camera-k), or only the size to scale the preset",
                k.cx, k.cy, k.width, k.height
            )));
        }
        Ok(k)
    }
}

/// Camera placed on a shell around a look-at point near the objects.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraPoseSpec {
    /// Distance from the look-at point, metres. Default 0.6..1.1 (Linemod-like).
    pub distance_m: Range,
    /// Elevation above the ground plane, degrees (90 = straight down). Default 20..80.
    pub elevation_deg: Range,
    /// Azimuth around the vertical axis, degrees. Default 0..360.
    pub azimuth_deg: Range,
    /// The look-at point is the centre of the placed objects plus a uniform offset up to this
    /// many metres per horizontal axis. Default 0.05.
    pub look_at_jitter_m: f64,
    /// Rotation about the optical axis, degrees. Default -10..10.
    pub inplane_deg: Range,
}

impl Default for CameraPoseSpec {
    fn default() -> Self {
        Self {
            distance_m: [0.6, 1.1],
            elevation_deg: [20.0, 80.0],
            azimuth_deg: [0.0, 360.0],
            look_at_jitter_m: 0.05,
            inplane_deg: [-10.0, 10.0],
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Orientation {
    /// Each object's `up` axis (default model +z) up, tilted by up to its `tilt_deg`, random
    /// rotation about the vertical (objects stand as scanned, or as `up` says).
    Upright,
    /// Uniformly random rotation, lowest point resting on the plane.
    Random,
}

/// How the sampled placement becomes the final one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlacementMode {
    /// The footprint sampler's poses as they are (default).
    #[default]
    Sample,
    /// The footprint poses lifted by `physics.drop_height_m`, dropped and settled by a
    /// physics engine (synthgen-physics); on failure, the footprint poses and a warning.
    Physics,
}

/// Drop-and-settle parameters for `placement.mode = "physics"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PhysicsSpec {
    /// Height each object is lifted above its resting footprint pose before the drop,
    /// metres. Default 0.02..0.1.
    pub drop_height_m: Range,
    /// Simulation step, seconds. Default 1/60.
    pub timestep_s: f64,
    /// Step budget per frame; a scene still moving after it falls back. Default 600.
    pub max_steps: u32,
    /// Coulomb friction coefficient of every contact. Default 0.7.
    pub friction: f64,
    /// Restitution (bounciness) 0..1. Default 0.05.
    pub restitution: f64,
    /// A scene is settled when every object's speed is below this, m/s (or rapier puts it
    /// to sleep). Default 0.005.
    pub settle_speed_m_s: f64,
}

impl Default for PhysicsSpec {
    fn default() -> Self {
        Self {
            drop_height_m: [0.02, 0.1],
            timestep_s: 1.0 / 60.0,
            max_steps: 600,
            friction: 0.7,
            restitution: 0.05,
            settle_speed_m_s: 0.005,
        }
    }
}

/// Objects on a ground plane (world z = 0, z up), non-overlapping footprints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlacementSpec {
    /// `sample` (default) or `physics`.
    pub mode: PlacementMode,
    /// Used when `mode = "physics"`.
    pub physics: PhysicsSpec,
    /// `upright` (default) or `random`.
    pub orientation: Orientation,
    /// Size of the rectangle (x, y) centred on the world origin where object centres land,
    /// metres. Default 0.5 x 0.5.
    pub area_m: [f64; 2],
    /// Extra clearance between footprints, metres. Default 0.005.
    pub min_gap_m: f64,
    /// Attempts per object before the frame's placement fails. Default 200.
    pub max_tries: u32,
    /// `[min, max]`: each frame places a random subset of the targets (the objects expanded
    /// by `count`) of a size drawn uniformly in min..=max (clamped to how many there are).
    /// Default: unset, every target in every frame.
    pub objects_per_frame: Option<[u32; 2]>,
    /// The probability that a target (after the frame's first) rests on top of a target
    /// already on the table, one no wider than it, instead of on the table (`scene fit`: the
    /// share of the real instances whose lowest point is off the table). Default 0.
    pub stack_prob: f64,
}

impl Default for PlacementSpec {
    fn default() -> Self {
        Self {
            mode: PlacementMode::Sample,
            physics: PhysicsSpec::default(),
            orientation: Orientation::Upright,
            area_m: [0.5, 0.5],
            min_gap_m: 0.005,
            max_tries: 200,
            objects_per_frame: None,
            stack_prob: 0.0,
        }
    }
}

/// The support plane, rendered as geometry (it has depth, like a real table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundSpec {
    /// Render the plane. Default true.
    pub visible: bool,
    /// Side length of the square plane, metres. Default 3.0.
    pub size_m: f64,
    /// sRGB colour range per channel; each frame draws a colour between these. Default
    /// a grey-brown table tone.
    pub color_min: [f32; 3],
    pub color_max: [f32; 3],
    /// Procedural checker/noise texture strength 0..1 (0 = plain). Default 0.3. Ignored
    /// with `texture_dir`.
    pub texture_strength: f32,
    /// Folder of PNG/JPEG images (relative to the spec file); each frame draws one and tiles
    /// the plane with it, times the frame's colour. Default: none (procedural tiles).
    pub texture_dir: Option<PathBuf>,
    /// Side of one texture tile on the plane along its x axis, metres (y keeps the image's
    /// aspect ratio). Default 0.5.
    pub texture_scale_m: f64,
}

impl Default for GroundSpec {
    fn default() -> Self {
        Self {
            visible: true,
            size_m: 3.0,
            color_min: [0.25, 0.22, 0.2],
            color_max: [0.75, 0.7, 0.65],
            texture_strength: 0.3,
            texture_dir: None,
            texture_scale_m: 0.5,
        }
    }
}

/// Point lights on a hemisphere above the scene plus an ambient term.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LightSpec {
    /// Number of point lights, inclusive range. Default 1..2.
    pub count: [u32; 2],
    /// Distance from the scene centre, metres. Default 1.0..3.0.
    pub distance_m: Range,
    /// Elevation, degrees. Default 30..85.
    pub elevation_deg: Range,
    /// Intensity multiplier. Default 0.6..1.2.
    pub intensity: Range,
    /// Max per-channel deviation from white. Default 0.15. Ignored when `temperature_k` is
    /// set.
    pub color_jitter: f64,
    /// Colour temperature range, kelvin (e.g. [2700, 6500]); each light's colour is the
    /// black-body colour of a uniform draw (`color::kelvin_to_rgb`). Default: unset (white
    /// with `color_jitter`).
    pub temperature_k: Option<Range>,
    /// Ambient light level. Default 0.15..0.35.
    pub ambient: Range,
    /// The lights cast shadows onto the objects, the ground and the walls (the embedded
    /// renderer's shadow maps, soft-edged; Cycles always shadows). Default true.
    pub shadows: bool,
    /// Screen-space ambient occlusion strength 0..1 (the embedded renderer): each pixel
    /// loses up to this share of its ambient light where nearby surfaces hide the sky
    /// (contact shadows where objects touch the table and each other). Default 0.6; 0 is off.
    pub ambient_occlusion: f64,
    /// Environment light (a two-colour hemisphere probe, the embedded renderer): the ambient
    /// light comes from a sky of this colour above the table and from the room and floor of
    /// `ground_color` below it, so a surface facing up gets `ambient × sky_color`, one facing
    /// down `ambient × ground_color`, and in between the mix by (1 + n·up) / 2. Linear
    /// multipliers of `ambient`. Default [1.2, 1.2, 1.3] (a bluish sky); both [1, 1, 1]: the
    /// same ambient from everywhere (the renderer before the environment light).
    pub sky_color: Option<[f64; 3]>,
    /// See `sky_color`. Default [0.6, 0.55, 0.5] (a warm, darker floor and room); [1, 1, 1]
    /// when only `sky_color` is given.
    pub ground_color: Option<[f64; 3]>,
}

impl Default for LightSpec {
    fn default() -> Self {
        Self {
            count: [1, 2],
            distance_m: [1.0, 3.0],
            elevation_deg: [30.0, 85.0],
            intensity: [0.6, 1.2],
            color_jitter: 0.15,
            temperature_k: None,
            ambient: [0.15, 0.35],
            shadows: true,
            ambient_occlusion: 0.6,
            sky_color: Some([1.2, 1.2, 1.3]),
            ground_color: Some([0.6, 0.55, 0.5]),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackgroundKind {
    /// A plain colour drawn from `color_min..color_max`.
    Color,
    /// Per-pixel uniform noise.
    Noise,
    /// Random crops from the images in `images_dir`.
    Images,
}

/// What is seen where no geometry is (above the horizon, past the plane).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BackgroundSpec {
    /// `color`, `noise` (default) or `images`.
    pub kind: BackgroundKind,
    pub color_min: [f32; 3],
    pub color_max: [f32; 3],
    /// Folder of PNG/JPEG images for `kind = "images"`.
    pub images_dir: Option<PathBuf>,
}

impl Default for BackgroundSpec {
    fn default() -> Self {
        Self {
            kind: BackgroundKind::Noise,
            color_min: [0.0, 0.0, 0.0],
            color_max: [1.0, 1.0, 1.0],
            images_dir: None,
        }
    }
}

/// Per-frame material jitter applied on top of each model's own colours.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MaterialSpec {
    /// Multiplicative brightness jitter per object, e.g. 0.8..1.2. Default 0.85..1.15.
    pub brightness: Range,
    /// Specular weight range. Default 0.05..0.4.
    pub specular: Range,
    /// Blinn-Phong exponent range. Default 8..64. Ignored when `roughness` is set.
    pub shininess: Range,
    /// Principled roughness range 0..1; when set, the Blinn-Phong exponent is
    /// n = 2 / r⁴ − 2 (Beckmann α = r², n = 2/α² − 2). Default: unset (use `shininess`).
    pub roughness: Option<Range>,
    /// Hue rotation per object, degrees (about the grey axis in linear RGB). Default 0..0.
    pub hue_deg: Range,
    /// The objects' specular model: `ggx` (the default; metallic-roughness: a GGX microfacet
    /// lobe with Smith shadowing and Schlick's Fresnel;
    /// F0 = 0.08 × specular for dielectrics, as in Disney's convention where 0.5 gives 0.04,
    /// and the base colour for metals). The embedded renderer's; Cycles' Principled BSDF is
    /// always GGX) or `phong` (Blinn-Phong, the renderer's model before GGX).
    pub shading: Shading,
    /// Metalness range per object (GGX): 0 dielectric, 1 metal. Default 0..0.3.
    pub metallic: Range,
}

/// The specular model of the embedded renderer (`[materials] shading`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shading {
    /// Lambert + Blinn-Phong (`specular`, `shininess`).
    Phong,
    /// Lambert + GGX microfacet specular with Fresnel (`specular`, `roughness`, `metallic`).
    #[default]
    Ggx,
}

impl Default for MaterialSpec {
    fn default() -> Self {
        Self {
            brightness: [0.85, 1.15],
            specular: [0.05, 0.4],
            shininess: [8.0, 64.0],
            roughness: None,
            hue_deg: [0.0, 0.0],
            shading: Shading::Ggx,
            metallic: [0.0, 0.3],
        }
    }
}

/// An object declared in the scene spec.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Mesh path, relative to the spec file.
    pub path: PathBuf,
    /// BOP object id. Default: order of appearance, from 1 (or the number in `obj_000008.ply`).
    pub obj_id: Option<u32>,
    /// `mm`, `m` or `auto` (default).
    pub units: Option<String>,
    /// How many instances per frame. Default 1.
    #[serde(default = "one")]
    pub count: u32,
    /// With `placement.orientation = "upright"`: the model axis that points up when the
    /// object stands (`+x`, `-x`, `+y`, `-y`, `+z`, `-z`), or `any` (one of the six drawn
    /// per instance: for objects whose rest pose is unknown). Default `+z`.
    #[serde(default)]
    pub up: UpAxis,
    /// With `upright`: the largest tilt away from that rest pose, degrees 0..90, drawn
    /// uniformly per frame about a random horizontal axis. Default 0.
    #[serde(default)]
    pub tilt_deg: f64,
}

impl ObjectSpec {
    /// An object at `path` with every other field at its default.
    pub fn new(path: impl Into<PathBuf>) -> ObjectSpec {
        ObjectSpec {
            path: path.into(),
            obj_id: None,
            units: None,
            count: 1,
            up: UpAxis::PlusZ,
            tilt_deg: 0.0,
        }
    }
}

fn one() -> u32 {
    1
}

impl SceneSpec {
    /// Reads a TOML spec. Object paths are resolved relative to the file's folder.
    pub fn from_toml_file(path: &Path) -> Result<SceneSpec, Error> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::ReadSpec {
            source,
            path: path.to_path_buf(),
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        let mut spec = Self::parse(&text, base).map_err(|e| match e {
            Error::ParseSpec { message, .. } => Error::ParseSpec {
                message,
                path: path.to_path_buf(),
            },
            other => other,
        })?;
        for o in &mut spec.objects {
            if o.path.is_relative() {
                o.path = base.join(&o.path);
            }
        }
        for m in &mut spec.distractors.meshes {
            if m.is_relative() {
                *m = base.join(&*m);
            }
        }
        for dir in [
            &mut spec.background.images_dir,
            &mut spec.ground.texture_dir,
            &mut spec.walls.texture_dir,
        ]
        .into_iter()
        .flatten()
        {
            if dir.is_relative() {
                *dir = base.join(&*dir);
            }
        }
        Ok(spec)
    }

    /// The files and folders the spec reads (its objects' meshes, distractor meshes, image
    /// folders, sensor file), by role: what a command writing a dataset must stay apart from.
    pub fn input_paths(&self) -> Vec<(&'static str, PathBuf)> {
        let mut out: Vec<(&'static str, PathBuf)> = self
            .objects
            .iter()
            .map(|o| ("scene object mesh", o.path.clone()))
            .collect();
        out.extend(
            self.distractors
                .meshes
                .iter()
                .map(|m| ("scene distractor mesh", m.clone())),
        );
        for (role, dir) in [
            ("background.images_dir", &self.background.images_dir),
            ("ground.texture_dir", &self.ground.texture_dir),
            ("walls.texture_dir", &self.walls.texture_dir),
            ("sensor file", &self.sensor.file),
        ] {
            if let Some(d) = dir {
                out.push((role, d.clone()));
            }
        }
        out
    }

    /// Parses a TOML spec; a `[sensor] file` is read relative to the current folder.
    pub fn from_toml_str(text: &str) -> Result<SceneSpec, Error> {
        Self::parse(text, Path::new("."))
    }

    /// Parses a spec whose relative `[sensor] file` lies under `base`.
    fn parse(text: &str, base: &Path) -> Result<SceneSpec, Error> {
        let parse_err = |e: toml::de::Error| Error::ParseSpec {
            message: e.to_string().trim().replace('\n', " "),
            path: PathBuf::from("<string>"),
        };
        let mut spec: SceneSpec = toml::from_str(text).map_err(parse_err)?;
        // serde fills a fixed-size array from the first values of a longer one: a range
        // written with 3 values would silently lose one.
        let given: toml::Value = toml::from_str(text).map_err(parse_err)?;
        let kept = toml::Value::try_from(&spec).map_err(|e| Error::ParseSpec {
            message: e.to_string(),
            path: PathBuf::from("<string>"),
        })?;
        check_nothing_dropped(&given, &kept, "")?;
        spec.sensor.resolve_file(base)?;
        spec.validate()?;
        Ok(spec)
    }

    pub fn to_toml(&self) -> String {
        // Serializing plain data with no maps keyed by non-strings cannot fail.
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// Checks ranges and values; errors name the field.
    /// Settings the spec holds that change nothing, as messages for the user: sensor
    /// sections beside a model that does not use them ([`SensorSpec::unused_sections`]),
    /// `materials.metallic` with Phong shading.
    pub fn unused_settings(&self) -> Vec<String> {
        let mut out = self.sensor.unused_sections();
        let m = &self.materials;
        if m.shading == Shading::Phong && m.metallic != MaterialSpec::default().metallic {
            out.push(format!(
                "materials.metallic {:?} is set but materials.shading is \"phong\", which has no metals: it has no effect (shading = \"ggx\" uses it)",
                m.metallic
            ));
        }
        out
    }

    pub fn validate(&self) -> Result<(), Error> {
        self.camera.intrinsics()?;
        let ranges: [(&str, Range); 11] = [
            ("camera_pose.distance_m", self.camera_pose.distance_m),
            ("camera_pose.elevation_deg", self.camera_pose.elevation_deg),
            ("camera_pose.azimuth_deg", self.camera_pose.azimuth_deg),
            ("camera_pose.inplane_deg", self.camera_pose.inplane_deg),
            ("lights.distance_m", self.lights.distance_m),
            ("lights.elevation_deg", self.lights.elevation_deg),
            ("lights.intensity", self.lights.intensity),
            ("lights.ambient", self.lights.ambient),
            ("materials.brightness", self.materials.brightness),
            ("materials.specular", self.materials.specular),
            ("materials.shininess", self.materials.shininess),
        ];
        for (name, [lo, hi]) in ranges {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(Error::InvalidSpec(format!(
                    "{name} must be finite with min <= max, got [{lo}, {hi}]"
                )));
            }
        }
        for (name, [lo, hi]) in [("materials.metallic", self.materials.metallic)] {
            if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi && hi <= 1.0) {
                return Err(Error::InvalidSpec(format!(
                    "{name} must lie in 0..1 with min <= max, got [{lo}, {hi}]"
                )));
            }
        }
        for (name, c) in [
            ("lights.sky_color", self.lights.sky_color),
            ("lights.ground_color", self.lights.ground_color),
        ] {
            if let Some(c) = c {
                if !c.iter().all(|v| v.is_finite() && (0.0..=10.0).contains(v)) {
                    return Err(Error::InvalidSpec(format!(
                        "{name} must be three multipliers in 0..10, got {c:?}"
                    )));
                }
            }
        }
        let ao = self.lights.ambient_occlusion;
        if !(0.0..=1.0).contains(&ao) {
            return Err(Error::InvalidSpec(format!(
                "lights.ambient_occlusion must lie in 0..1 (a strength), got {ao}"
            )));
        }
        // area_m is a size (x, y), not a range: x may be larger than y.
        let [ax, ay] = self.placement.area_m;
        if !(ax.is_finite() && ay.is_finite() && ax >= 0.0 && ay >= 0.0) {
            return Err(Error::InvalidSpec(format!(
                "placement.area_m must be two finite sizes >= 0, got [{ax}, {ay}]"
            )));
        }
        if self.camera_pose.distance_m[0] <= 0.0 {
            return Err(Error::InvalidSpec(
                "camera_pose.distance_m must be positive".into(),
            ));
        }
        let [e0, e1] = self.camera_pose.elevation_deg;
        if e0 < -90.0 || e1 > 90.0 {
            return Err(Error::InvalidSpec(
                "camera_pose.elevation_deg must lie within -90..90".into(),
            ));
        }
        if self.lights.count[0] > self.lights.count[1] || self.lights.count[1] > 16 {
            return Err(Error::InvalidSpec(
                "lights.count must be [min, max] with min <= max <= 16".into(),
            ));
        }
        let ph = &self.placement.physics;
        let [d0, d1] = ph.drop_height_m;
        if !(d0.is_finite() && d1.is_finite() && 0.0 <= d0 && d0 <= d1 && d1 <= 10.0) {
            return Err(Error::InvalidSpec(format!(
                "placement.physics.drop_height_m must be [min, max] with 0 <= min <= max <= 10, got [{d0}, {d1}]"
            )));
        }
        let checks = [
            ("placement.physics.timestep_s", ph.timestep_s, 1e-4, 0.1),
            ("placement.physics.friction", ph.friction, 0.0, 10.0),
            ("placement.physics.restitution", ph.restitution, 0.0, 1.0),
            (
                "placement.physics.settle_speed_m_s",
                ph.settle_speed_m_s,
                0.0,
                10.0,
            ),
        ];
        for (name, v, lo, hi) in checks {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err(Error::InvalidSpec(format!(
                    "{name} must lie within {lo}..{hi}, got {v}"
                )));
            }
        }
        if ph.max_steps == 0 {
            return Err(Error::InvalidSpec(
                "placement.physics.max_steps must be >= 1".into(),
            ));
        }
        if self.placement.max_tries == 0 {
            return Err(Error::InvalidSpec(
                "placement.max_tries must be >= 1".into(),
            ));
        }
        let sp = self.placement.stack_prob;
        if !(0.0..=1.0).contains(&sp) {
            return Err(Error::InvalidSpec(format!(
                "placement.stack_prob must be in 0..=1, got {sp}"
            )));
        }
        if let Some([lo, hi]) = self.placement.objects_per_frame {
            if lo == 0 || lo > hi {
                return Err(Error::InvalidSpec(format!(
                    "placement.objects_per_frame must be [min, max] with 1 <= min <= max, got [{lo}, {hi}]"
                )));
            }
        }
        for o in &self.objects {
            if !(o.tilt_deg.is_finite() && (0.0..=90.0).contains(&o.tilt_deg)) {
                return Err(Error::InvalidSpec(format!(
                    "objects.tilt_deg must lie within 0..90, got {} for {}",
                    o.tilt_deg,
                    o.path.display()
                )));
            }
        }
        self.validate_scene_extras()?;
        self.validate_surfaces()?;
        self.bin.validate()?;
        self.sensor.validate()?;
        if self.background.kind == BackgroundKind::Images && self.background.images_dir.is_none() {
            return Err(Error::InvalidSpec(
                "background.kind = \"images\" needs background.images_dir".into(),
            ));
        }
        Ok(())
    }
}

impl SceneSpec {
    /// Checks view rejection, distractors, light temperature and material jitter fields.
    pub(crate) fn validate_scene_extras(&self) -> Result<(), Error> {
        let c = &self.camera;
        if !(c.min_visib_fract.is_finite() && (0.0..=1.0).contains(&c.min_visib_fract)) {
            return Err(Error::InvalidSpec(format!(
                "camera.min_visib_fract must lie within 0..1, got {}",
                c.min_visib_fract
            )));
        }
        if c.max_view_tries == 0 || c.max_view_tries > 10_000 {
            return Err(Error::InvalidSpec(format!(
                "camera.max_view_tries must lie within 1..10000, got {}",
                c.max_view_tries
            )));
        }
        if let Some(t) = self.lights.temperature_k {
            check_range("lights.temperature_k", t, 1000.0, 40_000.0)?;
        }
        if let Some(r) = self.materials.roughness {
            check_range("materials.roughness", r, 0.01, 1.0)?;
        }
        check_range("materials.hue_deg", self.materials.hue_deg, -180.0, 180.0)?;
        let d = &self.distractors;
        if d.count[0] > d.count[1] || d.count[1] > 256 {
            return Err(Error::InvalidSpec(format!(
                "distractors.count must be [min, max] with min <= max <= 256, got {:?}",
                d.count
            )));
        }
        check_range("distractors.size_m", d.size_m, 1e-3, 10.0)?;
        if d.variants == 0 || d.variants > 64 {
            return Err(Error::InvalidSpec(format!(
                "distractors.variants must lie within 1..64, got {}",
                d.variants
            )));
        }
        for i in 0..3 {
            let (lo, hi) = (d.color_min[i], d.color_max[i]);
            if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi && hi <= 1.0) {
                return Err(Error::InvalidSpec(format!(
                    "distractors.color_min and color_max must be sRGB 0..1 with min <= max, got {:?} and {:?}",
                    d.color_min, d.color_max
                )));
            }
        }
        if !(0.0..=1.0).contains(&d.mesh_probability) {
            return Err(Error::InvalidSpec(format!(
                "distractors.mesh_probability must lie within 0..1, got {}",
                d.mesh_probability
            )));
        }
        if d.count[1] > 0 && d.shapes.is_empty() && d.meshes.is_empty() {
            return Err(Error::InvalidSpec(
                "distractors.count > 0 needs distractors.shapes or distractors.meshes".into(),
            ));
        }
        Ok(())
    }
}

impl SceneSpec {
    /// Checks the ground texture and `[walls]` fields.
    pub(crate) fn validate_surfaces(&self) -> Result<(), Error> {
        check_scale("ground.texture_scale_m", self.ground.texture_scale_m)?;
        check_colors("ground", self.ground.color_min, self.ground.color_max)?;
        let bg = &self.background;
        check_colors("background", bg.color_min, bg.color_max)?;
        let w = &self.walls;
        if w.count[0] > w.count[1] || w.count[1] > 4 {
            return Err(Error::InvalidSpec(format!(
                "walls.count must be [min, max] with min <= max <= 4, got {:?}",
                w.count
            )));
        }
        check_range("walls.distance_m", w.distance_m, 0.05, 1000.0)?;
        check_range("walls.height_m", w.height_m, 0.01, 1000.0)?;
        check_colors("walls", w.color_min, w.color_max)?;
        check_scale("walls.texture_scale_m", w.texture_scale_m)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_toml_is_default() {
        assert_eq!(SceneSpec::from_toml_str("").unwrap(), SceneSpec::default());
    }

    #[test]
    fn default_round_trips_through_toml() {
        let s = SceneSpec::default();
        assert_eq!(SceneSpec::from_toml_str(&s.to_toml()).unwrap(), s);
    }

    #[test]
    fn unknown_field_is_an_error() {
        let e = SceneSpec::from_toml_str("[camera]\nfocal = 3\n").unwrap_err();
        assert!(e.to_string().contains("focal"), "{e}");
    }

    #[test]
    fn inverted_range_is_an_error() {
        let e = SceneSpec::from_toml_str("[camera_pose]\ndistance_m = [2.0, 1.0]\n").unwrap_err();
        assert!(e.to_string().contains("camera_pose.distance_m"), "{e}");
    }

    /// `--image-size 320,240` alone used to keep the 640x480 preset's principal point, which
    /// then lay at the image's right edge.
    #[test]
    fn a_size_alone_scales_the_preset_and_the_principal_point_stays_inside() {
        let spec = |t: &str| SceneSpec::from_toml_str(t);
        let k = spec("[camera]\nwidth = 320\nheight = 240\n")
            .unwrap()
            .camera
            .intrinsics()
            .unwrap();
        let l = Intrinsics::LINEMOD;
        assert!((k.fx - l.fx / 2.0).abs() < 1e-9 && (k.fy - l.fy / 2.0).abs() < 1e-9);
        assert!((k.cx - ((l.cx + 0.5) / 2.0 - 0.5)).abs() < 1e-9);
        let e = spec("[camera]\nwidth = 320\nheight = 240\nfx = 300.0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("principal point (325.2611, 242.04899) lies outside the 320x240 image"),
            "{e}"
        );
    }

    /// Issue 13, item 14: serde took the first two values of a 3-value range and dropped the
    /// third without a word.
    #[test]
    fn three_value_range_is_an_error_not_truncated() {
        let e = SceneSpec::from_toml_str("[camera_pose]\ndistance_m = [0.5, 0.8, 1.2]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("camera_pose.distance_m has 3 values but takes 2"),
            "{e}"
        );
        let e = SceneSpec::from_toml_str("[ground]\ncolor_min = [0.1, 0.1, 0.1, 0.1]\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("ground.color_min has 4 values but takes 3"),
            "{e}"
        );
    }

    /// Issue 13, item 14: a colour range with min > max was accepted.
    #[test]
    fn inverted_colour_range_is_an_error() {
        for section in ["ground", "background"] {
            let text =
                format!("[{section}]\ncolor_min = [0.9, 0.1, 0.1]\ncolor_max = [0.2, 0.5, 0.5]\n");
            let e = SceneSpec::from_toml_str(&text).unwrap_err().to_string();
            assert!(
                e.contains(&format!("{section}.color_min and color_max")),
                "{e}"
            );
        }
    }

    #[test]
    fn area_is_a_size_not_a_range() {
        let s = SceneSpec::from_toml_str("[placement]\narea_m = [0.3, 0.25]\n").unwrap();
        assert_eq!(s.placement.area_m, [0.3, 0.25]);
        assert!(SceneSpec::from_toml_str("[placement]\narea_m = [-0.1, 0.2]\n").is_err());
    }

    #[test]
    fn sensor_section_parses_and_is_checked() {
        let s = SceneSpec::from_toml_str(
            "[sensor]\ndepth = \"d455\"\n[sensor.d455]\nsubpixel_sigma_px = 0.1\n",
        )
        .unwrap();
        assert_eq!(s.sensor.depth, DepthModel::D455);
        assert_eq!(s.sensor.d455.subpixel_sigma_px, 0.1);
        assert_eq!(s.sensor.d455.baseline_m, 0.095);
        let e = SceneSpec::from_toml_str("[sensor.d455]\nedge_dropout = 2.0\n").unwrap_err();
        assert!(e.to_string().contains("sensor.d455.edge_dropout"), "{e}");
        let e = SceneSpec::from_toml_str("[sensor]\ndepth = \"kinect2\"\n").unwrap_err();
        assert!(e.to_string().contains("kinect2"), "{e}");
    }

    #[test]
    fn objects_per_frame_up_and_tilt_parse_and_are_checked() {
        let s = SceneSpec::from_toml_str(
            "[placement]\nobjects_per_frame = [2, 4]\n[[objects]]\npath = \"a.obj\"\nup = \"-x\"\ntilt_deg = 10.0\n[[objects]]\npath = \"b.obj\"\n",
        )
        .unwrap();
        assert_eq!(s.placement.objects_per_frame, Some([2, 4]));
        assert_eq!(s.objects[0].up, UpAxis::MinusX);
        assert_eq!(s.objects[0].tilt_deg, 10.0);
        assert_eq!(s.objects[1], ObjectSpec::new("b.obj"));
        assert_eq!(SceneSpec::from_toml_str(&s.to_toml()).unwrap(), s);
        for (text, word) in [
            (
                "[placement]\nobjects_per_frame = [3, 2]\n",
                "objects_per_frame",
            ),
            (
                "[placement]\nobjects_per_frame = [0, 2]\n",
                "objects_per_frame",
            ),
            (
                "[[objects]]\npath = \"a.obj\"\ntilt_deg = 95.0\n",
                "tilt_deg",
            ),
            ("[[objects]]\npath = \"a.obj\"\nup = \"up\"\n", "up"),
        ] {
            let e = SceneSpec::from_toml_str(text).unwrap_err().to_string();
            assert!(e.contains(word), "{text}: {e}");
        }
    }

    #[test]
    fn camera_override() {
        let s = SceneSpec::from_toml_str("[camera]\npreset = \"d455\"\nfx = 400.0\n").unwrap();
        let k = s.camera.intrinsics().unwrap();
        assert_eq!(k.fx, 400.0);
        assert_eq!(k.width, 640);
    }
}
