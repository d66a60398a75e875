//! Moving objects (issue 46): meshes placed in the camera-and-lights file's
//! `"objects"` list (`{"mesh": "path.obj", "position": [x, y, z],
//! "scale": s, "rotation_deg": [x, y, z]}`, the path relative to the JSON
//! file), loaded once and placed in world space for each pose. They are
//! lit by the probes and the lights and cast shadows in the shadow maps;
//! they do not change the patches' light (the static scene's indirect
//! light ignores them, as Enlighten's dynamic objects do).

use crate::error::SceneError;
use crate::math::{cross, normalize, sub};
use crate::scene::Scene;
use std::path::Path;

pub use crate::scene_config::Placement;

/// Every object of `placements` loaded and placed (three vertices a
/// triangle); an error names the mesh file.
pub fn place_all(placements: &[Placement]) -> Result<Vec<Vertex>, SceneError> {
    let mut out = Vec::new();
    for p in placements {
        out.extend(Mesh::load(&p.mesh_path())?.placed(p));
    }
    Ok(out)
}

/// A loaded mesh: its triangles' corners, smooth normals (the file's, or
/// the mean of the faces' around each vertex) and each triangle's albedo.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub albedo: Vec<[f32; 3]>,
}

/// One vertex drawn: world position, unit normal, albedo.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub albedo: [f32; 3],
}

impl Mesh {
    /// The mesh of the scene file `path` ([`crate::scene::load`]: its
    /// repairs and errors, which name the file).
    pub fn load(path: &Path) -> Result<Mesh, SceneError> {
        Ok(Mesh::of_scene(&crate::scene::load(path)?))
    }

    /// The mesh of a loaded scene.
    pub fn of_scene(s: &Scene) -> Mesh {
        let normals = if s.normals.len() == s.positions.len() {
            s.normals.clone()
        } else {
            let mut acc = vec![[0.0f64; 3]; s.positions.len()];
            for t in &s.triangles {
                let p = t.map(|v| s.positions[v as usize].map(f64::from));
                // Area-weighted: the cross product's length.
                let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
                for &v in t {
                    for a in 0..3 {
                        acc[v as usize][a] += n[a];
                    }
                }
            }
            acc.into_iter()
                .map(|n| normalize(n).map(|v| v as f32))
                .collect()
        };
        Mesh {
            positions: s.positions.clone(),
            normals,
            triangles: s.triangles.clone(),
            albedo: s
                .triangle_material
                .iter()
                .map(|&m| s.materials[m as usize].albedo)
                .collect(),
        }
    }

    /// Its triangles' corners placed in world space (three vertices a
    /// triangle).
    pub fn placed(&self, at: &Placement) -> Vec<Vertex> {
        let mut out = Vec::with_capacity(3 * self.triangles.len());
        for (t, a) in self.triangles.iter().zip(&self.albedo) {
            for &v in t {
                let n = at.rotate(self.normals[v as usize]);
                out.push(Vertex {
                    position: at.apply(self.positions[v as usize]),
                    normal: normalize(n.map(f64::from)).map(|x| x as f32),
                    albedo: *a,
                });
            }
        }
        out
    }

    /// The bounds of its placed corners.
    pub fn bounds(&self, at: &Placement) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.positions {
            let q = at.apply(*p);
            for a in 0..3 {
                lo[a] = lo[a].min(f64::from(q[a]));
                hi[a] = hi[a].max(f64::from(q[a]));
            }
        }
        (lo, hi)
    }
}
