//! The moving objects the viewer places and moves (issue 46): the
//! camera-and-lights file's `"objects"`, their meshes loaded once, which
//! one is selected, and the edits its keys make (move along the camera's
//! axes by 1 % of the scene's diagonal, turn about the world's up axis).
//! Kept apart from the window so that it can be tested without one.

use super::controls::CameraRig;
use crate::core::objects::{Mesh, Placement, Vertex};
use glam::Vec3;

/// An edit of the selected object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ObjectEdit {
    /// Move by `(right, up, forward)` steps of the camera's axes.
    Move(Vec3),
    /// Turn about the vertical (y) axis by degrees.
    Turn(f32),
}

/// The objects, their meshes and the selection.
#[derive(Debug)]
pub struct ObjectRig {
    pub placements: Vec<Placement>,
    meshes: Vec<Mesh>,
    /// The object the keys move (`None`: the keys move lights).
    pub selected: Option<usize>,
    /// Scene units per step.
    pub step: f32,
    /// The placements changed since [`ObjectRig::take_changed`].
    changed: bool,
}

impl ObjectRig {
    /// Loads every placement's mesh (an error names the file).
    pub fn new(placements: &[Placement], diagonal: f32) -> anyhow::Result<ObjectRig> {
        let meshes = placements
            .iter()
            .map(|p| {
                let path = p.mesh_path();
                Mesh::load(&path)
                    .map_err(|e| anyhow::anyhow!("the moving object {}: {e}", path.display()))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        Ok(ObjectRig {
            placements: placements.to_vec(),
            meshes,
            selected: None,
            step: (0.01 * diagonal).max(1e-9),
            changed: true,
        })
    }

    /// Selects the next object; after the last, none (the keys move lights
    /// again).
    pub fn select_next(&mut self) {
        self.selected = match self.selected {
            None if !self.placements.is_empty() => Some(0),
            Some(i) if i + 1 < self.placements.len() => Some(i + 1),
            _ => None,
        };
    }

    /// Applies `edit` to the selected object (nothing without one).
    pub fn apply(&mut self, edit: ObjectEdit, rig: &CameraRig) {
        let Some(i) = self.selected else { return };
        let p = &mut self.placements[i];
        match edit {
            ObjectEdit::Move(d) => {
                let right = rig.forward.cross(rig.up).normalize_or(Vec3::X);
                let v = Vec3::from(p.position)
                    + (right * d.x + rig.up * d.y + rig.forward * d.z) * self.step;
                if v.is_finite() {
                    p.position = v.into();
                }
            }
            ObjectEdit::Turn(deg) => {
                p.rotation_deg[1] = (p.rotation_deg[1] + deg).rem_euclid(360.0);
            }
        }
        self.changed = true;
    }

    /// Whether the placements changed since the last call (and resets it).
    pub fn take_changed(&mut self) -> bool {
        std::mem::replace(&mut self.changed, false)
    }

    /// Every object's placed triangles.
    pub fn vertices(&self) -> Vec<Vertex> {
        self.meshes
            .iter()
            .zip(&self.placements)
            .flat_map(|(m, p)| m.placed(p))
            .collect()
    }

    /// Each object's bounds as placed.
    pub fn bounds(&self) -> Vec<([f64; 3], [f64; 3])> {
        self.meshes
            .iter()
            .zip(&self.placements)
            .map(|(m, p)| m.bounds(p))
            .collect()
    }

    /// A one-line description of the selection.
    pub fn describe(&self) -> String {
        match self.selected {
            None => String::new(),
            Some(i) => {
                let p = &self.placements[i];
                format!(
                    "object {}/{} {} at [{:.3}, {:.3}, {:.3}], turned {:.0}°",
                    i + 1,
                    self.placements.len(),
                    p.mesh,
                    p.position[0],
                    p.position[1],
                    p.position[2],
                    p.rotation_deg[1]
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::scene_config::Camera;

    #[test]
    fn objects_are_selected_in_turn_moved_and_turned() {
        let dir = std::env::temp_dir().join(format!("radiosity-objrig-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let obj = dir.join("tri.obj");
        std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let place = Placement {
            mesh: "tri.obj".into(),
            position: [0.0; 3],
            scale: 1.0,
            rotation_deg: [0.0; 3],
            resolved: Some(obj),
        };
        let mut rig = ObjectRig::new(&[place.clone(), place], 100.0).unwrap();
        assert!(rig.take_changed());
        assert!(!rig.take_changed());
        let cam = CameraRig::new(&Camera {
            position: [0.0, 0.0, 5.0],
            target: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 50.0,
        });
        // No selection: the keys do nothing to the objects.
        rig.apply(ObjectEdit::Move(Vec3::X), &cam);
        assert!(!rig.take_changed());
        rig.select_next();
        rig.select_next();
        assert_eq!(rig.selected, Some(1));
        // Right of a camera looking down −z is +x; a step is 1 unit.
        rig.apply(ObjectEdit::Move(Vec3::X), &cam);
        rig.apply(ObjectEdit::Turn(90.0), &cam);
        assert!(rig.take_changed());
        assert_eq!(rig.placements[1].position, [1.0, 0.0, 0.0]);
        assert_eq!(rig.placements[0].position, [0.0; 3]);
        // Turned 90° about y: the mesh's +x corner goes to −z.
        let v = rig.vertices();
        let moved = v[4].position;
        assert!(
            (moved[0] - 1.0).abs() < 1e-6 && (moved[2] + 1.0).abs() < 1e-6,
            "{moved:?}"
        );
        rig.select_next();
        assert_eq!(rig.selected, None);
        assert!(ObjectRig::new(
            &[Placement {
                resolved: Some(dir.join("missing.obj")),
                ..rig.placements[0].clone()
            }],
            1.0
        )
        .unwrap_err()
        .to_string()
        .contains("missing.obj"));
    }
}
