//! Pinhole cameras in the OpenCV convention (+X right, +Y down, +Z forward) with pixel
//! (i, j) covering [i, i+1) × [j, j+1) and sampled at its centre (i + 0.5, j + 0.5).

use crate::pose::Rigid;
use crate::{GeomError, Matrix3, Point3, Result, Vector3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: u32,
    pub height: u32,
}

impl PinholeCamera {
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64, width: u32, height: u32) -> Result<Self> {
        let cam = PinholeCamera {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        };
        cam.validate()?;
        Ok(cam)
    }

    pub fn validate(&self) -> Result<()> {
        let vals = [self.fx, self.fy, self.cx, self.cy];
        if vals.iter().any(|v| !v.is_finite()) || self.fx <= 0.0 || self.fy <= 0.0 {
            return Err(GeomError::InvalidArgument {
                primitive: "camera".into(),
                reason: format!(
                    "intrinsics fx={} fy={} cx={} cy={} must be finite with positive focal lengths",
                    self.fx, self.fy, self.cx, self.cy
                ),
            });
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(GeomError::InvalidArgument {
                primitive: "camera".into(),
                reason: format!(
                    "image size {}×{} must be between 1 and 16384 on each side",
                    self.width, self.height
                ),
            });
        }
        Ok(())
    }

    /// The same camera at half the resolution: pixel (i, j) covers pixels 2i..2i+1 × 2j..2j+1
    /// of this one, so its centre is their shared corner (`u / 2`: focal lengths and
    /// principal point halved), the size rounded up.
    pub fn halved(&self) -> PinholeCamera {
        PinholeCamera {
            fx: self.fx / 2.0,
            fy: self.fy / 2.0,
            cx: self.cx / 2.0,
            cy: self.cy / 2.0,
            width: self.width.div_ceil(2),
            height: self.height.div_ceil(2),
        }
    }

    /// From a 3×3 intrinsics matrix `[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`.
    pub fn from_matrix(k: &Matrix3, width: u32, height: u32) -> Result<Self> {
        PinholeCamera::new(k[(0, 0)], k[(1, 1)], k[(0, 2)], k[(1, 2)], width, height)
    }

    pub fn matrix(&self) -> Matrix3 {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Projects a camera-frame point to pixel coordinates (`u`, `v`); `None` behind the camera.
    pub fn project(&self, p: &Point3) -> Option<(f64, f64)> {
        if p.z <= 0.0 {
            return None;
        }
        Some((self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }

    /// The ray direction through pixel coordinates (u, v), with unit Z (so `t` is planar depth).
    pub fn ray_direction(&self, u: f64, v: f64) -> Vector3 {
        Vector3::new((u - self.cx) / self.fx, (v - self.cy) / self.fy, 1.0)
    }

    /// The same camera at another resolution (intrinsics rescaled per axis).
    pub fn resized(&self, width: u32, height: u32) -> PinholeCamera {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        PinholeCamera {
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
            width,
            height,
        }
    }

    /// A square camera with the given horizontal field of view (degrees at the interface).
    pub fn with_fov(fov_x_deg: f64, width: u32, height: u32) -> PinholeCamera {
        let fx = width as f64 * 0.5 / (fov_x_deg.to_radians() * 0.5).tan();
        PinholeCamera {
            fx,
            fy: fx,
            cx: width as f64 * 0.5,
            cy: height as f64 * 0.5,
            width,
            height,
        }
    }
}

/// `camera_from_world` for a camera at `eye` looking at `target`, OpenCV axes, with image up
/// as close to `up_world` as possible.
pub fn look_at(eye: &Point3, target: &Point3, up_world: &Vector3) -> Rigid {
    let forward = (target - eye).normalize();
    let mut right = (-up_world).cross(&forward);
    if right.norm() < 1e-9 {
        right = Vector3::new(0.0, 1.0, 0.0).cross(&forward);
        if right.norm() < 1e-9 {
            right = Vector3::x().cross(&forward);
        }
    }
    let right = right.normalize();
    let down = forward.cross(&right);
    // Rows of the world-to-camera rotation are the camera axes in world coordinates.
    let r = Matrix3::from_rows(&[right.transpose(), down.transpose(), forward.transpose()]);
    let rot = nalgebra::UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(r),
    );
    let t = -(rot * eye.coords);
    Rigid::from_parts(nalgebra::Translation3::from(t), rot)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_halved_camera_projects_to_half_the_pixel_coordinates() {
        let cam = PinholeCamera::new(520.0, 515.0, 338.0, 226.0, 641, 480).expect("valid");
        let half = cam.halved();
        assert_eq!((half.width, half.height), (321, 240));
        let p = Point3::new(0.13, -0.07, 1.7);
        let (u, v) = cam.project(&p).expect("in front");
        let (hu, hv) = half.project(&p).expect("in front");
        assert!((hu - u / 2.0).abs() < 1e-12 && (hv - v / 2.0).abs() < 1e-12);
        // A half-resolution pixel centre is the corner of its four pixels.
        assert_eq!(
            half.ray_direction(10.5, 20.5),
            cam.ray_direction(21.0, 41.0)
        );
    }

    #[test]
    fn projection_follows_the_pixel_centre_convention() {
        let cam = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("valid");
        let (u, v) = cam.project(&Point3::new(0.0, 0.0, 2.0)).expect("in front");
        assert_eq!((u, v), (160.0, 120.0));
        let d = cam.ray_direction(160.5, 120.5);
        let (u2, v2) = cam.project(&Point3::from(d * 3.0)).expect("in front");
        assert!((u2 - 160.5).abs() < 1e-12 && (v2 - 120.5).abs() < 1e-12);
        assert!(cam.project(&Point3::new(0.0, 0.0, -1.0)).is_none());
        assert!(PinholeCamera::new(f64::NAN, 1.0, 0.0, 0.0, 2, 2).is_err());
    }

    #[test]
    fn look_at_points_forward_with_image_up() {
        let cam_from_world = look_at(
            &Point3::new(0.0, -3.0, 0.0),
            &Point3::origin(),
            &Vector3::z(),
        );
        let target_in_cam = cam_from_world * Point3::origin();
        assert!((target_in_cam - Point3::new(0.0, 0.0, 3.0)).norm() < 1e-12);
        // World +Z (up) must appear as image up, i.e. camera −Y.
        let up_in_cam = cam_from_world.rotation * Vector3::z();
        assert!((up_in_cam - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
    }
}
