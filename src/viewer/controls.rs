//! What the viewer's keys and mouse do to the camera and the lights, kept
//! apart from the window so that it can be tested without one. Steps scale
//! with the scene: a move is 1 % of the scene's diagonal, so the same keys
//! work in millimetre and kilometre scenes.

use crate::core::scene_config::{Camera, Light, SceneConfig};
use glam::{Quat, Vec3};
use std::collections::BTreeMap;

/// The camera: a position, a view direction, the world's up (from the
/// camera/lights file) and the distance to the point it orbits.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraRig {
    pub position: Vec3,
    pub forward: Vec3,
    pub up: Vec3,
    pub distance: f32,
    pub fov_y_deg: f32,
}

impl CameraRig {
    pub fn new(c: &Camera) -> CameraRig {
        let p = Vec3::from(c.position);
        let t = Vec3::from(c.target);
        let up = Vec3::from(c.up).normalize_or(Vec3::Y);
        CameraRig {
            position: p,
            forward: (t - p).normalize_or(Vec3::NEG_Z),
            up,
            distance: (t - p).length().max(1e-6),
            fov_y_deg: c.fov_y_deg,
        }
    }

    /// The camera of the file format.
    pub fn camera(&self) -> Camera {
        Camera {
            position: self.position.into(),
            target: (self.position + self.forward * self.distance).into(),
            up: self.up.into(),
            fov_y_deg: self.fov_y_deg,
        }
    }

    fn right(&self) -> Vec3 {
        self.forward.cross(self.up).normalize_or(Vec3::X)
    }

    /// Turns the view by `yaw` about the up axis and `pitch` about the
    /// right axis (radians), keeping the forward direction off the poles.
    fn turn(&mut self, yaw: f32, pitch: f32) {
        let q = Quat::from_axis_angle(self.up, yaw) * Quat::from_axis_angle(self.right(), pitch);
        let f = (q * self.forward).normalize_or(self.forward);
        if f.dot(self.up).abs() < 0.995 {
            self.forward = f;
        } else {
            self.forward = (Quat::from_axis_angle(self.up, yaw) * self.forward).normalize();
        }
    }

    /// Orbits the point `distance` ahead by a mouse drag of `(dx, dy)`
    /// radians.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        let pivot = self.position + self.forward * self.distance;
        self.turn(-dx, -dy);
        self.position = pivot - self.forward * self.distance;
    }

    /// Looks around from where the camera stands (fly mode).
    pub fn look(&mut self, dx: f32, dy: f32) {
        self.turn(-dx, -dy);
    }

    /// Moves by `(right, up, forward)` steps of `step` scene units.
    pub fn fly(&mut self, d: Vec3, step: f32) {
        let r = self.right();
        self.position += (r * d.x + self.up * d.y + self.forward * d.z) * step;
    }

    /// Moves towards the orbit point (`k < 1`) or away (`k > 1`), the
    /// distance kept within [`MIN_DISTANCE`, `MAX_DISTANCE`] and the
    /// position finite (a wheel turned on and on stops there instead of
    /// reaching infinity, which the camera/lights file refuses).
    pub fn zoom(&mut self, k: f32) {
        let pivot = self.position + self.forward * self.distance;
        let distance = (self.distance * k).clamp(MIN_DISTANCE, MAX_DISTANCE);
        let position = pivot - self.forward * distance;
        if distance.is_finite() && position.is_finite() {
            self.distance = distance;
            self.position = position;
        }
    }
}

/// The closest the camera zooms to its orbit point, in scene units.
pub const MIN_DISTANCE: f32 = 1e-6;

/// The farthest the camera zooms from its orbit point, in scene units.
pub const MAX_DISTANCE: f32 = 1e30;

/// The largest and smallest nonzero component a light's power reaches by
/// [`Edit::Scale`]: presses beyond them do nothing, so that `+` held down
/// never reaches infinity (which the camera/lights file refuses and the
/// shaders turn into NaN) and `−` never reaches zero (from which `+` could
/// not bring the light back). 1e30 W/sr leaves room for `I / r²` in f32
/// down to distances of 1e-4.
pub const MAX_POWER: f32 = 1e30;
pub const MIN_POWER: f32 = 1e-30;

/// Irradiance of a sun added by key ([`Edit::AddSun`]): what a new point
/// light (`10⁴ step²` W/sr) gives at 20 steps, a fifth of the scene's
/// diagonal, whatever the scene's unit.
pub const SUN_IRRADIANCE: f32 = 25.0;

/// Colours the `C` key cycles through (multipliers of the light's
/// luminance-preserving power).
pub const COLOURS: [[f32; 3]; 6] = [
    [1.0, 1.0, 1.0],
    [1.0, 0.85, 0.6],
    [0.7, 0.85, 1.0],
    [1.0, 0.4, 0.3],
    [0.4, 1.0, 0.4],
    [0.4, 0.5, 1.0],
];

/// An edit of the lights or emission.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Edit {
    /// Move the selected light by `(right, up, forward)` steps of the
    /// camera's axes.
    Move(Vec3),
    /// Turn the selected light's direction by yaw, pitch (radians).
    Turn(f32, f32),
    /// Multiply its power.
    Scale(f32),
    /// Widen (`+`) or narrow (`−`) a spot's cone by degrees.
    Cone(f32),
    /// Next colour of [`COLOURS`].
    Colour,
    /// A point light at the camera.
    AddPoint,
    /// A spot light at the camera, looking where it looks.
    AddSpot,
    /// A directional light (a sun) shining where the camera looks.
    AddSun,
    Remove,
    /// Switch every emissive material off, or back on.
    ToggleEmission,
}

/// The lights and emission being edited, and which light is selected.
#[derive(Clone, Debug, PartialEq)]
pub struct LightRig {
    pub lights: Vec<Light>,
    pub emission: BTreeMap<String, f32>,
    pub selected: usize,
    /// Scene units per step (1 % of the scene's diagonal).
    pub step: f32,
    /// Irradiance at one step's distance of a new light (W/sr of new
    /// lights are this times step², so they light what is near).
    pub colour_index: usize,
    emissive: Vec<String>,
}

impl LightRig {
    /// `config`'s lights and emission; `diagonal` of the scene's bounds;
    /// the names of the emissive materials.
    pub fn new(config: &SceneConfig, diagonal: f32, emissive: Vec<String>) -> LightRig {
        LightRig {
            lights: config.lights.clone(),
            emission: config.emission.clone(),
            selected: 0,
            step: (0.01 * diagonal).max(1e-9),
            colour_index: 0,
            emissive,
        }
    }

    /// Selects the next light.
    pub fn select_next(&mut self) {
        if !self.lights.is_empty() {
            self.selected = (self.selected + 1) % self.lights.len();
        }
    }

    /// Applies `edit` with the camera `rig` giving the axes and the new
    /// lights' place.
    pub fn apply(&mut self, edit: Edit, rig: &CameraRig) {
        let right = rig.forward.cross(rig.up).normalize_or(Vec3::X);
        let step = self.step;
        match edit {
            Edit::AddPoint | Edit::AddSpot | Edit::AddSun => {
                // 10 W/sr at a scene of 10 units: scaled by step² so that
                // a new light gives comparable irradiance at any scale.
                let i = 1e4 * step * step;
                let p: [f32; 3] = rig.position.into();
                self.lights.push(match edit {
                    Edit::AddPoint => Light::Point {
                        position: p,
                        intensity: [i; 3],
                    },
                    Edit::AddSpot => Light::Spot {
                        position: p,
                        direction: rig.forward.into(),
                        intensity: [4.0 * i; 3],
                        cone_angle_deg: 30.0,
                        beam_angle_deg: 20.0,
                    },
                    // What a new point light gives 20 steps away, 25 in
                    // the scene's units at any scale (i / (20 step)²).
                    _ => Light::Directional {
                        direction: rig.forward.into(),
                        irradiance: [SUN_IRRADIANCE; 3],
                    },
                });
                self.selected = self.lights.len() - 1;
                return;
            }
            Edit::ToggleEmission => {
                let off = self
                    .emissive
                    .iter()
                    .any(|m| self.emission.get(m).copied().unwrap_or(1.0) != 0.0);
                for m in &self.emissive {
                    self.emission.insert(m.clone(), if off { 0.0 } else { 1.0 });
                }
                return;
            }
            _ => {}
        }
        if self.lights.is_empty() {
            return;
        }
        self.selected = self.selected.min(self.lights.len() - 1);
        if edit == Edit::Remove {
            self.lights.remove(self.selected);
            self.selected = self.selected.saturating_sub(1);
            return;
        }
        let colour_index = (self.colour_index + 1) % COLOURS.len();
        let light = &mut self.lights[self.selected];
        let (position, direction, power, cone) = match light {
            Light::Directional {
                direction,
                irradiance,
            } => (None, Some(direction), irradiance, None),
            Light::Point {
                position,
                intensity,
            } => (Some(position), None, intensity, None),
            Light::Spot {
                position,
                direction,
                intensity,
                cone_angle_deg,
                beam_angle_deg,
            } => (
                Some(position),
                Some(direction),
                intensity,
                Some((cone_angle_deg, beam_angle_deg)),
            ),
        };
        match edit {
            Edit::Move(d) => {
                if let Some(p) = position {
                    let v =
                        Vec3::from(*p) + (right * d.x + rig.up * d.y + rig.forward * d.z) * step;
                    *p = v.into();
                }
            }
            Edit::Turn(yaw, pitch) => {
                if let Some(dir) = direction {
                    let d = Vec3::from(*dir).normalize_or(Vec3::NEG_Y);
                    let axis = d.cross(rig.up).normalize_or(right);
                    let q = Quat::from_axis_angle(rig.up, yaw) * Quat::from_axis_angle(axis, pitch);
                    *dir = (q * d).normalize_or(d).into();
                }
            }
            Edit::Scale(k) => {
                let scaled = power.map(|c| c * k);
                let top = scaled.iter().fold(0.0f32, |m, &c| m.max(c));
                if scaled.iter().all(|c| c.is_finite()) && (MIN_POWER..=MAX_POWER).contains(&top) {
                    *power = scaled;
                }
            }
            Edit::Cone(deg) => {
                if let Some((cone, beam)) = cone {
                    let ratio = *beam / cone.max(1e-3);
                    *cone = (*cone + deg).clamp(1.0, 89.0);
                    *beam = (ratio * *cone).min(*cone);
                }
            }
            Edit::Colour => {
                let lum = 0.2126 * power[0] + 0.7152 * power[1] + 0.0722 * power[2];
                let c = COLOURS[colour_index];
                let cl = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
                *power = c.map(|v| v * lum / cl);
                self.colour_index = colour_index;
            }
            _ => {}
        }
    }

    /// A one-line description of the selected light.
    pub fn describe(&self) -> String {
        match self.lights.get(self.selected) {
            None => "no lights (N adds a point, B a spot)".into(),
            Some(l) => {
                let kind = match l {
                    Light::Directional { .. } => "directional",
                    Light::Point { .. } => "point",
                    Light::Spot { .. } => "spot",
                };
                format!("light {}/{} {kind}", self.selected + 1, self.lights.len())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            position: [0.0, 1.0, 5.0],
            target: [0.0, 1.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 50.0,
        }
    }

    #[test]
    fn the_rig_round_trips_the_camera_and_orbits_at_a_fixed_distance() {
        let mut rig = CameraRig::new(&camera());
        let c = rig.camera();
        assert_eq!(c.position, [0.0, 1.0, 5.0]);
        assert!((Vec3::from(c.target) - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6);
        let pivot = Vec3::new(0.0, 1.0, 0.0);
        for _ in 0..50 {
            rig.orbit(0.1, 0.03);
            assert!(((rig.position - pivot).length() - 5.0).abs() < 1e-3);
            assert!(rig.forward.dot(rig.up).abs() < 0.996);
        }
        rig.zoom(0.5);
        assert!(((rig.position - pivot).length() - 2.5).abs() < 1e-3);
    }

    #[test]
    fn light_edits_move_scale_recolour_add_and_remove() {
        let config = SceneConfig {
            sky: None,
            objects: Vec::new(),
            camera: camera(),
            lights: vec![Light::Spot {
                position: [0.0, 3.0, 0.0],
                direction: [0.0, -1.0, 0.0],
                intensity: [10.0; 3],
                cone_angle_deg: 40.0,
                beam_angle_deg: 20.0,
            }],
            units: "m".into(),
            description: String::new(),
            emission: BTreeMap::new(),
        };
        let cam = CameraRig::new(&config.camera);
        let mut rig = LightRig::new(&config, 100.0, vec!["lamp".into()]);
        rig.apply(Edit::Move(Vec3::new(0.0, 1.0, 0.0)), &cam);
        rig.apply(Edit::Scale(2.0), &cam);
        rig.apply(Edit::Cone(10.0), &cam);
        rig.apply(Edit::Colour, &cam);
        match &rig.lights[0] {
            Light::Spot {
                position,
                intensity,
                cone_angle_deg,
                beam_angle_deg,
                ..
            } => {
                assert!((position[1] - 4.0).abs() < 1e-5);
                let lum = 0.2126 * intensity[0] + 0.7152 * intensity[1] + 0.0722 * intensity[2];
                assert!((lum - 20.0).abs() < 1e-3, "colour keeps luminance");
                assert_eq!(*cone_angle_deg, 50.0);
                assert!((beam_angle_deg - 25.0).abs() < 1e-4);
            }
            l => panic!("{l:?}"),
        }
        rig.apply(Edit::AddPoint, &cam);
        assert_eq!(rig.lights.len(), 2);
        assert_eq!(rig.selected, 1);
        rig.apply(Edit::Remove, &cam);
        assert_eq!(rig.lights.len(), 1);
        // A sun along the view, selected, and turned by the turn keys.
        rig.apply(Edit::AddSun, &cam);
        assert_eq!(rig.selected, 1);
        let sun = |r: &LightRig| match r.lights[1] {
            Light::Directional {
                direction,
                irradiance,
            } => (Vec3::from(direction), irradiance),
            ref l => panic!("{l:?}"),
        };
        assert_eq!(sun(&rig), (cam.forward, [SUN_IRRADIANCE; 3]));
        rig.apply(Edit::Turn(0.1, 0.0), &cam);
        assert!((sun(&rig).0.angle_between(cam.forward) - 0.1).abs() < 1e-5);
        rig.apply(Edit::Remove, &cam);
        assert_eq!(rig.lights.len(), 1);
        rig.apply(Edit::ToggleEmission, &cam);
        assert_eq!(rig.emission.get("lamp"), Some(&0.0));
        rig.apply(Edit::ToggleEmission, &cam);
        assert_eq!(rig.emission.get("lamp"), Some(&1.0));
    }

    fn power(l: &Light) -> [f32; 3] {
        match l {
            Light::Directional { irradiance, .. } => *irradiance,
            Light::Point { intensity, .. } | Light::Spot { intensity, .. } => *intensity,
        }
    }

    /// `+` or `−` held down (a thousand presses each way) stops at the
    /// bounds instead of reaching infinity or zero, and comes back; the
    /// wheel likewise keeps the camera finite.
    #[test]
    fn held_keys_and_wheels_stop_at_finite_bounds() {
        let config = SceneConfig {
            sky: None,
            objects: Vec::new(),
            camera: camera(),
            lights: vec![Light::Point {
                position: [0.0, 3.0, 0.0],
                intensity: [10.0, 5.0, 0.0],
            }],
            units: "m".into(),
            description: String::new(),
            emission: BTreeMap::new(),
        };
        let cam = CameraRig::new(&config.camera);
        let mut rig = LightRig::new(&config, 100.0, vec![]);
        for _ in 0..1000 {
            rig.apply(Edit::Scale(1.25), &cam);
        }
        let p = power(&rig.lights[0]);
        assert!(
            p[0] <= MAX_POWER && p[0] > MAX_POWER / 1.25 && p[2] == 0.0,
            "{p:?}"
        );
        assert!((p[0] / p[1] - 2.0).abs() < 1e-5, "the colour stays: {p:?}");
        for _ in 0..2000 {
            rig.apply(Edit::Scale(0.8), &cam);
        }
        let p = power(&rig.lights[0]);
        assert!(
            p[0] >= MIN_POWER && p[0] < MIN_POWER / 0.8 && p[1] > 0.0,
            "{p:?}"
        );
        rig.apply(Edit::Scale(1.25), &cam);
        assert!(power(&rig.lights[0])[0] > p[0], "and + brings it back");
        let mut c = CameraRig::new(&config.camera);
        for _ in 0..2000 {
            c.zoom(1.0 / 0.9);
        }
        assert!(
            c.position.is_finite() && c.distance == MAX_DISTANCE,
            "{c:?}"
        );
        for _ in 0..4000 {
            c.zoom(0.9);
        }
        assert!(
            c.position.is_finite() && c.distance == MIN_DISTANCE,
            "{c:?}"
        );
        let saved = c.camera();
        assert!(saved
            .position
            .iter()
            .chain(&saved.target)
            .all(|v| v.is_finite()));
    }
}
