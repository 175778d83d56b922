//! Pinhole camera intrinsics and presets.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::Error;

/// Pinhole intrinsics in pixels for an image of `width` x `height`. OpenCV convention: the
/// centre of the top-left pixel is (0, 0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// Named camera presets (`--camera NAME`).
pub const CAMERA_PRESETS: &[&str] = &["linemod", "d455", "d455-720", "ycbv", "ycbv-cmu"];

impl Intrinsics {
    /// The Linemod (Kinect v1) camera, as in BOP's lm/lmo `camera.json`.
    pub const LINEMOD: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 572.4114,
        fy: 573.57043,
        cx: 325.2611,
        cy: 242.04899,
    };
    /// Intel RealSense D455 depth stream at 640x480: typical factory calibration of one unit
    /// (focal lengths differ by a few pixels between units; pass your own K for real data).
    pub const D455_640: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 382.613,
        fy: 382.613,
        cx: 320.183,
        cy: 236.455,
    };
    /// Intel RealSense D455 depth stream at 1280x720 (typical factory calibration, as above).
    pub const D455_1280: Intrinsics = Intrinsics {
        width: 1280,
        height: 720,
        fx: 637.688,
        fy: 637.688,
        cx: 640.305,
        cy: 360.758,
    };
    /// The YCB-Video camera of the UW rig, scenes 0–59 (BOP ycbv `camera_uw.json`, YCB-Video's
    /// `asus-uw.json`): an Asus Xtion Pro Live.
    pub const YCBV: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 1066.778,
        fy: 1067.487,
        cx: 312.9869,
        cy: 241.3109,
    };
    /// The YCB-Video camera of the CMU rig, scenes 60–91 (BOP ycbv `camera_cmu.json`,
    /// YCB-Video's `asus-cmu.json`).
    pub const YCBV_CMU: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 1077.836,
        fy: 1078.189,
        cx: 323.7872,
        cy: 279.6921,
    };

    pub fn preset(name: &str) -> Result<Intrinsics, Error> {
        match name.to_ascii_lowercase().as_str() {
            "linemod" | "lm" | "lmo" => Ok(Self::LINEMOD),
            "d455" | "d455-640" => Ok(Self::D455_640),
            "d455-720" | "d455-1280" => Ok(Self::D455_1280),
            "ycbv" | "ycb-video" | "ycbv-uw" => Ok(Self::YCBV),
            "ycbv-cmu" => Ok(Self::YCBV_CMU),
            _ => Err(Error::UnknownCamera(name.to_string())),
        }
    }

    /// Row-major 3x3 K, as BOP's `cam_K`.
    pub fn k_row_major(&self) -> [f64; 9] {
        [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]
    }

    /// Builds intrinsics from a row-major K and an image size.
    pub fn from_k(k: &[f64; 9], width: u32, height: u32) -> Intrinsics {
        Intrinsics {
            width,
            height,
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
        }
    }

    pub fn validate(&self) -> Result<(), Error> {
        let ok = self.width > 0
            && self.height > 0
            && self.width <= 16384
            && self.height <= 16384
            && [self.fx, self.fy, self.cx, self.cy]
                .iter()
                .all(|v| v.is_finite())
            && self.fx > 0.0
            && self.fy > 0.0;
        if ok {
            Ok(())
        } else {
            Err(Error::InvalidSpec(format!(
                "camera intrinsics must be finite with positive focal lengths and size 1..=16384, got {self:?}"
            )))
        }
    }

    /// Projects a camera-frame point (metres) to pixel coordinates; `None` behind the camera.
    pub fn project(&self, p_cam: DVec3) -> Option<(f64, f64)> {
        (p_cam.z > 0.0).then(|| {
            (
                self.fx * p_cam.x / p_cam.z + self.cx,
                self.fy * p_cam.y / p_cam.z + self.cy,
            )
        })
    }

    /// Back-projects pixel (u, v) at depth `z_m` along the optical axis into the camera frame.
    pub fn back_project(&self, u: f64, v: f64, z_m: f64) -> DVec3 {
        DVec3::new(
            (u - self.cx) * z_m / self.fx,
            (v - self.cy) * z_m / self.fy,
            z_m,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn project_back_project_round_trip(u in 0.0f64..640.0, v in 0.0f64..480.0, z in 0.1f64..5.0) {
            let k = Intrinsics::LINEMOD;
            let p = k.back_project(u, v, z);
            let (u2, v2) = k.project(p).unwrap();
            prop_assert!((u - u2).abs() < 1e-9 && (v - v2).abs() < 1e-9);
        }
    }

    #[test]
    fn presets_resolve() {
        for name in CAMERA_PRESETS {
            assert!(Intrinsics::preset(name).unwrap().validate().is_ok());
        }
        assert!(Intrinsics::preset("kinect9").is_err());
    }

    /// The YCB-Video rigs' colour cameras, exactly as asus-uw.json / asus-cmu.json give them.
    #[test]
    fn ycbv_presets_are_exact() {
        let uw = Intrinsics::preset("ycbv").unwrap();
        assert_eq!(
            (uw.fx, uw.fy, uw.cx, uw.cy),
            (1066.778, 1067.487, 312.9869, 241.3109)
        );
        let cmu = Intrinsics::preset("ycbv-cmu").unwrap();
        assert_eq!(
            (cmu.fx, cmu.fy, cmu.cx, cmu.cy),
            (1077.836, 1078.189, 323.7872, 279.6921)
        );
        assert_eq!((cmu.width, cmu.height), (640, 480));
    }

    #[test]
    fn k_round_trip() {
        let k = Intrinsics::LINEMOD;
        assert_eq!(Intrinsics::from_k(&k.k_row_major(), 640, 480), k);
    }
}
