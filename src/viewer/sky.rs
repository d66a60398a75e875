//! The viewer's sky: which sky lights the window, cycled with a key among
//! the file's own and a few made for any scene, and the sun of the sun and
//! sky moved by keys, the sky following it (the model is evaluated for
//! each position: `crates/core/src/sky/preetham.rs`). The sky's sun joins
//! the lights of each frame ([`SkyRig::frame_lights`]).

use crate::core::scene_config::Light;
use crate::core::sky::Sky;

/// The sun's step per key press, degrees.
pub const SUN_STEP_DEG: f32 = 5.0;

/// The made skies' scale: the sun and sky's intensity is such that its
/// sun at the zenith gives about [`super::controls::SUN_IRRADIANCE`] (the
/// viewer's new sun, 25 in the scene's units at any scale; the model's
/// own sun is about 140 W/m²), and the other skies give a horizontal
/// surface under them a fifth of it, as a clear sky does beside its sun.
const SUN_AND_SKY_INTENSITY: f32 = super::controls::SUN_IRRADIANCE / 140.0;

/// The skies cycled and the sun's position.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyRig {
    /// The file's sky, if it has one.
    file: Option<Sky>,
    /// Index into [`SkyRig::names`].
    index: usize,
    /// The sun and sky's sun: elevation and azimuth (from `−z` towards
    /// `+x`), degrees.
    pub elevation: f32,
    pub azimuth: f32,
    turbidity: f32,
    intensity: f32,
}

impl SkyRig {
    /// Starts with the file's sky (a sun and sky's sun where it is).
    pub fn new(file: Option<Sky>) -> SkyRig {
        let (mut elevation, mut azimuth, mut turbidity, mut intensity) =
            (45.0, 30.0, 3.0, SUN_AND_SKY_INTENSITY);
        if let Some(Sky::Sunsky {
            sun_direction: d,
            turbidity: t,
            intensity: k,
        }) = &file
        {
            let len = d.iter().map(|v| v * v).sum::<f32>().sqrt();
            elevation = (d[1] / len).clamp(-1.0, 1.0).asin().to_degrees();
            azimuth = d[0].atan2(-d[2]).to_degrees();
            (turbidity, intensity) = (*t, *k);
        }
        SkyRig {
            index: 0,
            file,
            elevation,
            azimuth,
            turbidity,
            intensity,
        }
    }

    /// The skies in the cycle's order.
    fn names(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.file.is_some() {
            v.push("the file's");
        }
        v.extend(["none", "sun and sky", "overcast", "clear gradient"]);
        v
    }

    /// The next sky in the cycle.
    pub fn next(&mut self) {
        self.index = (self.index + 1) % self.names().len();
    }

    /// Moves the sun by the given degrees (elevation within ±90°); the
    /// sky shown becomes the sun and sky if it was not already (a file's
    /// sun and sky stays itself, following the sun).
    pub fn move_sun(&mut self, d_elevation: f32, d_azimuth: f32) {
        self.elevation = (self.elevation + d_elevation).clamp(-90.0, 90.0);
        self.azimuth = (self.azimuth + d_azimuth).rem_euclid(360.0);
        let file_sunsky = self.index == 0 && matches!(self.file, Some(Sky::Sunsky { .. }));
        if !file_sunsky && self.names()[self.index] != "sun and sky" {
            self.index = self
                .names()
                .iter()
                .position(|&n| n == "sun and sky")
                .unwrap_or(0);
        }
    }

    /// The unit vector towards the sun.
    fn sun_direction(&self) -> [f32; 3] {
        let (e, a) = (self.elevation.to_radians(), self.azimuth.to_radians());
        [e.cos() * a.sin(), e.sin(), -e.cos() * a.cos()]
    }

    /// The sky shown.
    pub fn current(&self) -> Option<Sky> {
        let names = self.names();
        Some(match names[self.index] {
            "the file's" => match self.file.clone()? {
                Sky::Sunsky { .. } => Sky::Sunsky {
                    sun_direction: self.sun_direction(),
                    turbidity: self.turbidity,
                    intensity: self.intensity,
                },
                s => s,
            },
            "none" => return None,
            "sun and sky" => Sky::Sunsky {
                sun_direction: self.sun_direction(),
                turbidity: self.turbidity,
                intensity: self.intensity,
            },
            // π L = a fifth of the sun's irradiance.
            "overcast" => Sky::Uniform {
                radiance: [0.2 * super::controls::SUN_IRRADIANCE / std::f32::consts::PI; 3],
            },
            _ => {
                let k = 0.2 * super::controls::SUN_IRRADIANCE / std::f32::consts::PI;
                Sky::Gradient {
                    zenith: [0.5 * k, 0.8 * k, 1.6 * k],
                    horizon: [1.2 * k, 1.2 * k, 1.1 * k],
                    ground: [0.3 * k, 0.3 * k, 0.25 * k],
                }
            }
        })
    }

    /// `lights` and the shown sky's sun, if it has one above the horizon.
    pub fn frame_lights(&self, lights: &[Light]) -> Vec<Light> {
        let mut all = lights.to_vec();
        all.extend(
            self.current()
                .and_then(|s| s.sun())
                .map(crate::core::scene_config::sun_light),
        );
        all
    }

    /// For the window's title.
    pub fn describe(&self) -> String {
        let name = self.names()[self.index];
        match self.current() {
            Some(Sky::Sunsky { .. }) => format!(
                "sky: {name}, sun {:.0}° up, {:.0}° round",
                self.elevation, self.azimuth
            ),
            _ => format!("sky: {name}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cycle visits every sky and comes back; moving the sun shows the
    /// sun and sky, whose sun is a light travelling away from it.
    #[test]
    fn skies_cycle_and_the_sun_moves() {
        let mut rig = SkyRig::new(Some(Sky::Uniform { radiance: [1.0; 3] }));
        assert_eq!(rig.current(), Some(Sky::Uniform { radiance: [1.0; 3] }));
        let mut seen = vec![rig.describe()];
        for _ in 0..4 {
            rig.next();
            seen.push(rig.describe());
        }
        rig.next();
        assert_eq!(rig.describe(), seen[0]);
        assert!(seen.contains(&"sky: none".to_string()), "{seen:?}");
        rig.move_sun(-45.0, 0.0);
        assert!(matches!(rig.current(), Some(Sky::Sunsky { .. })));
        assert_eq!(rig.elevation, 0.0);
        // At the horizon: no sun yet.
        assert_eq!(rig.frame_lights(&[]).len(), 0);
        rig.move_sun(30.0, 90.0);
        let lights = rig.frame_lights(&[]);
        match lights[..] {
            [Light::Directional { direction, .. }] => {
                // The sun 30° up, 30° + 90° round from −z towards +x: the
                // light travels away from it.
                let (e, a) = (30f32.to_radians(), 120f32.to_radians());
                let to_sun = [e.cos() * a.sin(), e.sin(), -e.cos() * a.cos()];
                for k in 0..3 {
                    assert!((direction[k] + to_sun[k]).abs() < 1e-6, "{direction:?}");
                }
            }
            _ => panic!("{lights:?}"),
        }
        // A file's sun and sky keeps its turbidity and intensity and
        // follows the keys.
        let mut rig = SkyRig::new(Some(Sky::Sunsky {
            sun_direction: [0.0, 1.0, -1.0],
            turbidity: 5.0,
            intensity: 2.0,
        }));
        assert!((rig.elevation - 45.0).abs() < 1e-4 && rig.azimuth.abs() < 1e-4);
        rig.move_sun(5.0, 0.0);
        match rig.current() {
            Some(Sky::Sunsky {
                turbidity,
                intensity,
                ..
            }) => assert_eq!((turbidity, intensity), (5.0, 2.0)),
            s => panic!("{s:?}"),
        }
        assert!(rig.describe().starts_with("sky: the file's"));
    }
}
