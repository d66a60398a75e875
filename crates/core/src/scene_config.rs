//! The camera-and-lights file that accompanies every scene (`NAME.json`
//! next to `NAME.obj`): where the viewer starts and which dynamic lights the
//! run time evaluates each frame (docs/design.md, run time step 1).
//!
//! The format is JSON, read with `deny_unknown_fields` so a misspelt key is
//! an error instead of a silently ignored setting, and validated after
//! parsing: every number finite, directions non-zero, `0 < fov_y_deg < 180`,
//! `0 < cone_angle_deg ≤ 90`, `0 ≤ beam_angle_deg ≤ cone_angle_deg`, light
//! powers non-negative. `scenes/README.md` documents the format.
//!
//! Units. Lengths are in the scene's unit (`units`, e.g. `"m"` or `"mm"`);
//! radiometric quantities use that same length unit, so an intensity `I`
//! (W/sr) gives the irradiance `I cos θ / r²` with `r` in scene units, and a
//! directional light's `irradiance` is per scene unit² on a surface facing
//! the light.

use crate::math::{cross, dot, normalize, sub};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A scene's camera and dynamic lights.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneConfig {
    /// The initial (and benchmark) camera.
    pub camera: Camera,
    /// The dynamic lights; may be empty (a scene lit by emission only).
    pub lights: Vec<Light>,
    /// The length unit of the scene's coordinates, e.g. `"m"` or `"mm"`.
    pub units: String,
    /// A human-readable description of the scene and its lights; optional
    /// (empty when absent).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// Run-time scale of each emissive material's `Ke`, by material name
    /// (0 switches it off); materials not listed keep scale 1.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub emission: BTreeMap<String, f32>,
    /// The sky ([`crate::sky`]); none: black, as before skies existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky: Option<crate::sky::Sky>,
    /// Moving objects ([`crate::objects`]): meshes placed in the scene,
    /// lit by the probes; none when absent.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub objects: Vec<Placement>,
}

/// One moving object as the JSON places it ([`crate::objects`] loads and
/// places its mesh).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// The mesh file (OBJ or glTF), relative to the JSON file.
    pub mesh: String,
    /// Where the mesh's origin goes.
    pub position: [f32; 3],
    /// Uniform scale (> 0); 1 when absent.
    #[serde(default = "one")]
    pub scale: f32,
    /// Rotations about x, then y, then z, in degrees; none when absent.
    #[serde(default)]
    pub rotation_deg: [f32; 3],
    /// `mesh` resolved against the JSON file's directory when the file was
    /// read (`scene_config::load`); not written back.
    #[serde(skip)]
    pub resolved: Option<std::path::PathBuf>,
}

fn one() -> f32 {
    1.0
}

impl Placement {
    /// The mesh file: resolved against the JSON file's directory, or as
    /// written.
    pub fn mesh_path(&self) -> std::path::PathBuf {
        self.resolved
            .clone()
            .unwrap_or_else(|| std::path::PathBuf::from(&self.mesh))
    }

    /// The point `p` of the mesh in world space: scaled, rotated about x,
    /// y then z, moved.
    pub fn apply(&self, p: [f32; 3]) -> [f32; 3] {
        let r = self.rotate(p.map(|v| v * self.scale));
        std::array::from_fn(|a| r[a] + self.position[a])
    }

    /// The direction `d` turned as the mesh is (no scale, no move).
    pub fn rotate(&self, d: [f32; 3]) -> [f32; 3] {
        let [ax, ay, az] = self.rotation_deg.map(|a| a.to_radians());
        let (s, c) = ax.sin_cos();
        let d = [d[0], c * d[1] - s * d[2], s * d[1] + c * d[2]];
        let (s, c) = ay.sin_cos();
        let d = [c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]];
        let (s, c) = az.sin_cos();
        [c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]]
    }
}

/// The farthest a camera may be from the scene's centre, in scene
/// extents ([`SceneConfig::check_in_scene`]): f32 keeps 24 bits, so at a
/// million extents a ray's position is resolved to 6e-2 of the scene.
pub const MAX_CAMERA_DISTANCE: f64 = 1e6;

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// The eye position.
    pub position: [f32; 3],
    /// A point the camera looks at (must differ from `position`).
    pub target: [f32; 3],
    /// The up direction (non-zero, not parallel to the view direction).
    pub up: [f32; 3],
    /// The full vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f32,
}

/// A dynamic light, tagged by `"type"` in the JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Light {
    /// A light at infinity (the sun). `direction` is the direction the light
    /// travels (from the light into the scene); `irradiance` (W/m² in metre
    /// scenes, W per scene unit² in general) is received by a surface
    /// perpendicular to it.
    Directional {
        direction: [f32; 3],
        irradiance: [f32; 3],
    },
    /// A spot light at `position` shining along `direction`. Its intensity
    /// is `intensity` (W/sr) within `beam_angle_deg` of the axis, falls
    /// linearly in angle to zero at `cone_angle_deg` (both half angles, in
    /// degrees) and is zero beyond: the profile of Mitsuba 3's `spot`
    /// emitter with `cutoff_angle = cone_angle_deg` and
    /// `beam_width = beam_angle_deg`.
    Spot {
        position: [f32; 3],
        direction: [f32; 3],
        intensity: [f32; 3],
        cone_angle_deg: f32,
        beam_angle_deg: f32,
    },
    /// An isotropic point light at `position` with intensity `intensity`
    /// (W/sr) in every direction.
    Point {
        position: [f32; 3],
        intensity: [f32; 3],
    },
}

/// An error reading, validating or writing a scene configuration file.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read or written.
    #[error("cannot access scene configuration {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid JSON or does not match the format (unknown
    /// field, missing field, wrong type); serde_json gives the position.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    /// The file parsed but a value is out of its valid range.
    #[error("{path}: {invalid}")]
    Invalid {
        path: PathBuf,
        invalid: InvalidField,
    },
    /// The sky's environment map could not be read.
    #[error("{path}: sky.file: {source}")]
    EnvMap {
        path: PathBuf,
        #[source]
        source: crate::sky::envmap::EnvMapError,
    },
}

pub use crate::error::InvalidField;

fn show3(v: [f32; 3]) -> String {
    format!("[{}, {}, {}]", v[0], v[1], v[2])
}

fn invalid(field: String, value: String, message: &str) -> InvalidField {
    InvalidField {
        field,
        value,
        message: message.to_string(),
    }
}

fn finite3(field: String, v: [f32; 3]) -> Result<(), InvalidField> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(invalid(
            field,
            show3(v),
            "every component must be a finite number",
        ))
    }
}

fn direction3(field: String, v: [f32; 3]) -> Result<(), InvalidField> {
    finite3(field.clone(), v)?;
    if v.iter().all(|&x| x == 0.0) {
        return Err(invalid(field, show3(v), "a direction must be non-zero"));
    }
    Ok(())
}

/// The largest light power component accepted (W/sr for point and spot
/// lights, W/m² for the sun, in the scene's units): direct light, its sums
/// over lights and the gathers are f32 (at most 3.4e38), so a power near
/// that range overflows on any surface within a unit of the light (a light
/// of 1e38 W/sr gave a NaN image and exit 0). Larger scenes' lights
/// (the Cornell box's in millimetres, 7.4e4 W/sr) stay far below.
pub const MAX_LIGHT_POWER: f32 = 1e36;

fn power3(field: String, v: [f32; 3]) -> Result<(), InvalidField> {
    finite3(field.clone(), v)?;
    if v.iter().any(|&x| x < 0.0) {
        return Err(invalid(field, show3(v), "light power must be non-negative"));
    }
    if v.iter().any(|&x| x > MAX_LIGHT_POWER) {
        return Err(invalid(
            field,
            show3(v),
            "light power must be at most 1e36: beyond, the light on surfaces near it overflows \
             f32 (an exposure can show any image of smaller lights)",
        ));
    }
    Ok(())
}

fn angle(
    field: String,
    x: f32,
    lo_open: f32,
    hi: f32,
    hi_inclusive: bool,
) -> Result<(), InvalidField> {
    let ok = x.is_finite() && x > lo_open && if hi_inclusive { x <= hi } else { x < hi };
    if ok {
        Ok(())
    } else {
        let range = if hi_inclusive {
            format!("must lie in ({lo_open}, {hi}] degrees")
        } else {
            format!("must lie in ({lo_open}, {hi}) degrees")
        };
        Err(invalid(field, x.to_string(), &range))
    }
}

impl SceneConfig {
    /// Checks every value against its valid range; the error names the
    /// field and its value.
    pub fn validate(&self) -> Result<(), InvalidField> {
        if self.units.trim().is_empty() {
            return Err(invalid(
                "units".into(),
                format!("{:?}", self.units),
                "the length unit must be named, e.g. \"m\" or \"mm\"",
            ));
        }
        let c = &self.camera;
        finite3("camera.position".into(), c.position)?;
        finite3("camera.target".into(), c.target)?;
        direction3("camera.up".into(), c.up)?;
        let view = [
            c.target[0] - c.position[0],
            c.target[1] - c.position[1],
            c.target[2] - c.position[2],
        ];
        if view.iter().all(|&x| x == 0.0) {
            return Err(invalid(
                "camera.target".into(),
                show3(c.target),
                "the target must differ from the camera position",
            ));
        }
        // In f64: a camera far out (1e30) or a tiny up vector (1e-30) is
        // valid, and in f32 their squared lengths leave the range.
        let f = |a: [f32; 3]| a.map(f64::from);
        let view_dir = normalize(sub(f(c.target), f(c.position)));
        let side = cross(view_dir, normalize(f(c.up)));
        if !(dot(side, side).sqrt() >= 1e-6) {
            return Err(invalid(
                "camera.up".into(),
                show3(c.up),
                "the up direction must not be parallel to the view direction",
            ));
        }
        angle("camera.fov_y_deg".into(), c.fov_y_deg, 0.0, 180.0, false)?;
        for (name, &s) in &self.emission {
            if !(s.is_finite() && s >= 0.0) {
                return Err(invalid(
                    format!("emission.{name}"),
                    s.to_string(),
                    "an emission scale must be a finite number ≥ 0",
                ));
            }
        }
        if let Some(sky) = &self.sky {
            sky.validate()?;
        }
        for (i, o) in self.objects.iter().enumerate() {
            let f = |name: &str| format!("objects[{i}].{name}");
            if o.mesh.trim().is_empty() {
                return Err(invalid(
                    f("mesh"),
                    format!("{:?}", o.mesh),
                    "a mesh file must be named",
                ));
            }
            finite3(f("position"), o.position)?;
            finite3(f("rotation_deg"), o.rotation_deg)?;
            if !(o.scale.is_finite() && o.scale > 0.0) {
                return Err(invalid(
                    f("scale"),
                    o.scale.to_string(),
                    "must be a finite number > 0",
                ));
            }
        }
        for (i, light) in self.lights.iter().enumerate() {
            let f = |name: &str| format!("lights[{i}].{name}");
            match light {
                Light::Directional {
                    direction,
                    irradiance,
                } => {
                    direction3(f("direction"), *direction)?;
                    power3(f("irradiance"), *irradiance)?;
                }
                Light::Spot {
                    position,
                    direction,
                    intensity,
                    cone_angle_deg,
                    beam_angle_deg,
                } => {
                    finite3(f("position"), *position)?;
                    direction3(f("direction"), *direction)?;
                    power3(f("intensity"), *intensity)?;
                    angle(f("cone_angle_deg"), *cone_angle_deg, 0.0, 90.0, true)?;
                    let b = *beam_angle_deg;
                    if !(b.is_finite() && b >= 0.0 && b <= *cone_angle_deg) {
                        return Err(invalid(
                            f("beam_angle_deg"),
                            b.to_string(),
                            "must lie in [0, cone_angle_deg] degrees",
                        ));
                    }
                }
                Light::Point {
                    position,
                    intensity,
                } => {
                    finite3(f("position"), *position)?;
                    power3(f("intensity"), *intensity)?;
                }
            }
        }
        Ok(())
    }

    /// Checks the camera against the scene it looks at (bounds `lo..hi`):
    /// its position within [`MAX_CAMERA_DISTANCE`] extents of the scene's
    /// centre. Farther, f32 rays from it cannot resolve the scene (a
    /// camera at x = 1e38 drew a black image with exit 0).
    pub fn check_in_scene(&self, lo: [f32; 3], hi: [f32; 3]) -> Result<(), InvalidField> {
        let extent = (0..3)
            .map(|a| f64::from(hi[a]) - f64::from(lo[a]))
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let centre: [f64; 3] = std::array::from_fn(|a| 0.5 * (f64::from(lo[a]) + f64::from(hi[a])));
        let p = self.camera.position.map(f64::from);
        let d = sub(p, centre);
        let distance = dot(d, d).sqrt() / extent;
        if !(distance <= MAX_CAMERA_DISTANCE) {
            return Err(invalid(
                "camera.position".into(),
                show3(self.camera.position),
                &format!(
                    "the camera is {distance:.3e} scene extents from the scene's centre; at most \
                     {MAX_CAMERA_DISTANCE:e} (f32 rays cannot resolve the scene from farther)"
                ),
            ));
        }
        Ok(())
    }

    /// Parses and validates a configuration from JSON text; `path` only
    /// names the source in errors.
    pub fn from_json(text: &str, path: &Path) -> Result<SceneConfig, ConfigError> {
        let config: SceneConfig = serde_json::from_str(text).map_err(|e| {
            let full = e.to_string();
            let suffix = format!(" at line {} column {}", e.line(), e.column());
            let message = full.strip_suffix(&suffix).unwrap_or(&full).to_string();
            ConfigError::Parse {
                path: path.to_path_buf(),
                line: e.line(),
                column: e.column(),
                message,
            }
        })?;
        config.validate().map_err(|invalid| ConfigError::Invalid {
            path: path.to_path_buf(),
            invalid,
        })?;
        let mut config = config;
        // Object meshes are found beside the JSON file.
        let base = path.parent().unwrap_or(Path::new(""));
        for o in &mut config.objects {
            o.resolved = Some(base.join(&o.mesh));
        }
        if let Some(sky) = &mut config.sky {
            let base = path.parent().unwrap_or(Path::new(""));
            sky.load_map(base).map_err(|source| ConfigError::EnvMap {
                path: path.to_path_buf(),
                source,
            })?;
            // Again with the map read: its brightness against the bound.
            sky.validate().map_err(|invalid| ConfigError::Invalid {
                path: path.to_path_buf(),
                invalid,
            })?;
        }
        Ok(config)
    }

    /// The lights of a frame: the file's lights, then the sky's sun when
    /// it has one ([`crate::sky::Sky::sun`]).
    pub fn frame_lights(&self) -> Vec<Light> {
        let mut lights = self.lights.clone();
        lights.extend(self.sky.as_ref().and_then(|s| s.sun()).map(sun_light));
        lights
    }

    /// The configuration as pretty-printed JSON with a final newline. The
    /// text depends only on the values (fields in declaration order, floats
    /// in their shortest round-trip form), so it is deterministic.
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("a SceneConfig always serialises");
        s.push('\n');
        s
    }

    /// Validates the configuration and writes it to `path` as pretty JSON.
    pub fn save(&self, path: &Path) -> Result<(), ConfigError> {
        self.validate().map_err(|invalid| ConfigError::Invalid {
            path: path.to_path_buf(),
            invalid,
        })?;
        std::fs::write(path, self.to_json()).map_err(|source| ConfigError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// Reads, parses and validates the scene configuration at `path`.
pub fn load(path: &Path) -> Result<SceneConfig, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    SceneConfig::from_json(&text, path)
}

/// A sky's sun as the directional light it is.
pub fn sun_light(sun: crate::sky::Sun) -> Light {
    Light::Directional {
        direction: sun.direction,
        irradiance: sun.irradiance,
    }
}
