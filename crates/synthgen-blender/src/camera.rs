//! OpenCV intrinsics and camera frame → Blender's camera, the one place where the two
//! conventions meet.
//!
//! Blender's camera looks down its −z axis with +y up; OpenCV's looks down +z with +y down.
//! The Blender scene built by `blender/synthgen_scene.py` uses the OpenCV camera frame as its
//! world frame, so the Blender camera object sits at the origin with the rotation
//! [`OPENCV_CAM_FROM_BLENDER_CAM`] and every pose the sampler gives (`cam_from_obj`, lights,
//! the ground) goes in unchanged.
//!
//! Blender has one focal length. `fx != fy` (the Linemod camera: 572.41 vs 573.57) is exact
//! through a scale of the scene along the camera's y axis by `fy / fx` (a parent empty
//! above every object and light; the camera is not under it). Projection and depth along the
//! optical axis are then exactly those of K. Pixel aspect is not used: Blender 5.0.1 cannot
//! write a multilayer EXR when the pixel aspect is not 1.

use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::Intrinsics;

/// Maps Blender camera coordinates (x right, y up, z backward) to OpenCV camera coordinates
/// (x right, y down, z forward). Its own inverse.
pub const OPENCV_CAM_FROM_BLENDER_CAM: DMat3 = DMat3::from_cols(
    DVec3::new(1.0, 0.0, 0.0),
    DVec3::new(0.0, -1.0, 0.0),
    DVec3::new(0.0, 0.0, -1.0),
);

/// The sensor width every camera gets; only `lens_mm / sensor_width_mm` matters.
pub const SENSOR_WIDTH_MM: f64 = 36.0;

/// Blender camera data (`sensor_fit = 'HORIZONTAL'`, pixel aspect 1) for a pinhole K.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlenderCamera {
    pub width: u32,
    pub height: u32,
    pub lens_mm: f64,
    pub sensor_width_mm: f64,
    /// `camera.data.shift_x`, `shift_y`, in units of the image width.
    pub shift_x: f64,
    pub shift_y: f64,
    /// Scale of the scene along the OpenCV camera y axis: `fy / fx`.
    pub y_scale: f64,
}

impl BlenderCamera {
    /// OpenCV puts the centre of the top-left pixel at (0, 0); Blender's image plane spans
    /// `[0, W] x [0, H]` with pixel centres at half integers and the (unshifted) principal
    /// point at `(W / 2, H / 2)`, i.e. at OpenCV `((W − 1) / 2, (H − 1) / 2)`.
    pub fn from_intrinsics(k: &Intrinsics) -> BlenderCamera {
        let (w, h) = (f64::from(k.width), f64::from(k.height));
        BlenderCamera {
            width: k.width,
            height: k.height,
            lens_mm: k.fx * SENSOR_WIDTH_MM / w,
            sensor_width_mm: SENSOR_WIDTH_MM,
            shift_x: ((w - 1.0) * 0.5 - k.cx) / w,
            shift_y: (k.cy - (h - 1.0) * 0.5) / w,
            y_scale: k.fy / k.fx,
        }
    }

    /// Where Blender's camera model puts a point of the Blender world (= the OpenCV camera
    /// frame scaled by `y_scale` along y), in OpenCV pixel coordinates. Written after
    /// Blender's `BKE_camera_params_compute_viewplane` (horizontal fit, pixel aspect 1), so
    /// the tests can check it against `Intrinsics::project`.
    pub fn project_world_point(&self, p_world: DVec3) -> Option<(f64, f64)> {
        let p_bcam = OPENCV_CAM_FROM_BLENDER_CAM * p_world; // the camera's rotation is its own inverse
        if p_bcam.z >= 0.0 {
            return None;
        }
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let f_px = self.lens_mm / self.sensor_width_mm * w;
        // Continuous coordinates from the image's left and bottom edges.
        let x_left = f_px * p_bcam.x / -p_bcam.z + 0.5 * w - self.shift_x * w;
        let y_bottom = f_px * p_bcam.y / -p_bcam.z + 0.5 * h - self.shift_y * w;
        Some((x_left - 0.5, (h - y_bottom) - 0.5))
    }

    /// A camera-frame point as placed in the Blender world (the y scale applied).
    pub fn world_from_cv_point(&self, p_cam: DVec3) -> DVec3 {
        DVec3::new(p_cam.x, p_cam.y * self.y_scale, p_cam.z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blender_camera_looks_down_minus_z_with_y_up() {
        // OpenCV forward (+z) is Blender's −z; OpenCV down (+y) is Blender's −y.
        let m = OPENCV_CAM_FROM_BLENDER_CAM;
        assert_eq!(m * DVec3::new(0.0, 0.0, -1.0), DVec3::Z);
        assert_eq!(m * DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.0, -1.0, 0.0));
        assert_eq!(m * m, DMat3::IDENTITY);
        assert!(
            (m.determinant() - 1.0).abs() < 1e-12,
            "a rotation, not a mirror"
        );
    }

    #[test]
    fn blender_projection_equals_opencv_projection() {
        let ks = [
            Intrinsics::LINEMOD,
            Intrinsics::YCBV,
            Intrinsics::D455_1280,
            Intrinsics {
                width: 64,
                height: 48,
                fx: 60.0,
                fy: 75.0,
                cx: 20.3,
                cy: 30.9,
            },
        ];
        for k in ks {
            let cam = BlenderCamera::from_intrinsics(&k);
            for (i, p) in [
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(0.1, -0.05, 0.7),
                DVec3::new(-0.2, 0.13, 1.9),
                DVec3::new(0.03, 0.2, 0.4),
            ]
            .into_iter()
            .enumerate()
            {
                let want = k.project(p).unwrap();
                let got = cam.project_world_point(cam.world_from_cv_point(p)).unwrap();
                assert!(
                    (want.0 - got.0).abs() < 1e-9 && (want.1 - got.1).abs() < 1e-9,
                    "{k:?} point {i}: opencv {want:?} blender {got:?}"
                );
            }
            assert!(cam
                .project_world_point(DVec3::new(0.0, 0.0, -1.0))
                .is_none());
        }
    }

    #[test]
    fn principal_point_at_image_centre_means_no_shift() {
        let k = Intrinsics {
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 500.0,
            cx: 319.5,
            cy: 239.5,
        };
        let c = BlenderCamera::from_intrinsics(&k);
        assert_eq!((c.shift_x, c.shift_y, c.y_scale), (0.0, 0.0, 1.0));
        assert!((c.lens_mm - 500.0 * 36.0 / 640.0).abs() < 1e-12);
    }
}
