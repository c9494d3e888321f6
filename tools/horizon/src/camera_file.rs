//! The camera file of the conventions (TOML): `width`, `height`, `fx`, `fy`, `cx`, `cy`, `k1`,
//! `k2`, optional `mount_roll_deg`, `mount_pitch_deg`.

use crate::Error;
use serde::{Deserialize, Serialize};
use skyframe_core::horizon::Camera;
use std::path::Path;

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    #[serde(default)]
    pub k1: f32,
    #[serde(default)]
    pub k2: f32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mount_roll_deg: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mount_pitch_deg: Option<f32>,
}

impl CameraFile {
    pub fn load(path: &Path) -> Result<Camera, Error> {
        let text =
            skyframe_input_files::read_text(path, "camera", skyframe_input_files::CONFIG_LIMIT)
                .map_err(Error::input)?;
        Self::parse(&text).map_err(|e| Error::input(format!("{}: {e}", path.display())))
    }

    pub fn parse(text: &str) -> Result<Camera, String> {
        let file: CameraFile = toml::from_str(text).map_err(|e| {
            // toml's message spans several lines (a snippet of the file); keep one.
            let span = e
                .span()
                .map(|s| format!("byte {}: ", s.start))
                .unwrap_or_default();
            format!("{span}{}", e.message())
        })?;
        let camera = file.to_camera();
        if !camera.is_valid() {
            return Err("fx and fy must be positive, width and height non-zero, all finite".into());
        }
        Ok(camera)
    }

    pub fn to_camera(&self) -> Camera {
        Camera {
            width: self.width,
            height: self.height,
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
            k1: self.k1,
            k2: self.k2,
            mount_roll_rad: self.mount_roll_deg.unwrap_or(0.0).to_radians(),
            mount_pitch_rad: self.mount_pitch_deg.unwrap_or(0.0).to_radians(),
        }
    }

    pub fn from_camera(camera: &Camera) -> Self {
        let mount = |rad: f32| (rad != 0.0).then(|| rad.to_degrees());
        CameraFile {
            width: camera.width,
            height: camera.height,
            fx: camera.fx,
            fy: camera.fy,
            cx: camera.cx,
            cy: camera.cy,
            k1: camera.k1,
            k2: camera.k2,
            mount_roll_deg: mount(camera.mount_roll_rad),
            mount_pitch_deg: mount(camera.mount_pitch_rad),
        }
    }

    pub fn to_toml(camera: &Camera) -> String {
        toml::to_string(&Self::from_camera(camera)).unwrap_or_default()
    }
}

/// The camera assumed without `--camera`: 60° horizontal field of view, no distortion.
pub const DEFAULT_FOV_DEG: f32 = 60.0;

pub fn default_camera(width: usize, height: usize) -> Camera {
    Camera::ideal(width as u32, height as u32, DEFAULT_FOV_DEG.to_radians())
}
