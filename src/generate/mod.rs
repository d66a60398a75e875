//! Deterministic generators for the bundled test scenes, written as
//! OBJ + MTL plus a camera-and-lights JSON file (`crate::core::scene_config`).
//!
//! The scenes serve the measures of docs/design.md section 3: the Cornell box
//! from its published data, analytic configurations with known view
//! factors (Howell's catalog C-11, C-14, coaxial disks), a closed cube for
//! the furnace test, and an architectural interior at the thesis's scale.
//! `scenes/README.md` documents each scene; the committed files under
//! `scenes/NAME/` are exactly what `write_bundled` writes (a test checks it).
//!
//! Output is byte-for-byte deterministic: positions are rounded to a fixed
//! number of decimals when created and printed with exactly that many,
//! triangles are grouped by material in a fixed order, and nothing depends
//! on hash order, time or threads.

mod analytic;
mod cornell;
mod interior;
mod mesh;
mod stress;

pub use analytic::{
    coaxial_disks_factor, parallel_rectangles_factor, perpendicular_rectangles_factor,
};
pub use mesh::{MaterialDef, Mesh};

use crate::core::scene_config::{ConfigError, SceneConfig};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The names of the bundled scenes, in the order they are documented.
pub const BUNDLED: &[&str] = &[
    "cornell_box",
    "parallel_squares",
    "perpendicular_squares",
    "coaxial_disks",
    "closed_cube",
    "interior",
];

/// Scenes generated on demand for accuracy tests and reports, not
/// committed (`stress.rs` describes them).
pub const STRESS: &[&str] = &[
    "cornell_panel",
    "cornell_published",
    "two_rooms",
    "odd_box",
    "cluttered_room",
];

/// An error generating or writing a bundled scene.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// The name is not one of `BUNDLED`.
    #[error("unknown scene {name:?}; the bundled scenes are: {known}")]
    UnknownScene { name: String, known: String },
    /// The generator produced degenerate triangles (a bug in the generator).
    #[error("scene {name}: the generator produced {count} degenerate triangle(s)")]
    Degenerate { name: String, count: usize },
    /// A file or directory could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The camera/lights configuration is invalid (a bug in the generator).
    #[error(transparent)]
    Config(#[from] ConfigError),
}

/// A generated scene in memory: exactly what `write_bundled` writes.
#[derive(Clone, Debug, PartialEq)]
pub struct GeneratedScene {
    /// The scene's name (one of `BUNDLED`); also the files' base name.
    pub name: String,
    /// Comment lines written at the top of the OBJ and MTL files
    /// (provenance and units).
    pub header: Vec<String>,
    /// The number of decimals of every written coordinate.
    pub decimals: usize,
    /// The triangles, grouped by material.
    pub mesh: Mesh,
    /// The materials, in MTL order; triangles refer to them by index.
    pub materials: Vec<MaterialDef>,
    /// The camera and lights written to `NAME.json`.
    pub config: SceneConfig,
}

impl GeneratedScene {
    /// The index of the material called `name`, if any.
    pub fn material_index(&self, name: &str) -> Option<u32> {
        self.materials
            .iter()
            .position(|m| m.name == name)
            .map(|i| i as u32)
    }

    /// The OBJ text: header comments, `mtllib`, one `v` line per position
    /// with exactly `decimals` decimals, then one `usemtl` group per
    /// material with its `f` lines (1-based indices).
    pub fn obj_text(&self) -> String {
        let mut s =
            String::with_capacity(self.mesh.positions.len() * 32 + self.mesh.triangles.len() * 24);
        for line in &self.header {
            let _ = writeln!(s, "# {line}");
        }
        let _ = writeln!(
            s,
            "# {} vertices, {} triangles, {} materials",
            self.mesh.positions.len(),
            self.mesh.triangles.len(),
            self.materials.len()
        );
        let _ = writeln!(s, "mtllib {}.mtl", self.name);
        let _ = writeln!(s, "o {}", self.name);
        let d = self.decimals;
        for p in &self.mesh.positions {
            let _ = writeln!(s, "v {:.*} {:.*} {:.*}", d, p[0], d, p[1], d, p[2]);
        }
        let mut current = None;
        for (t, tri) in self.mesh.triangles.iter().enumerate() {
            let m = self.mesh.triangle_material[t];
            if current != Some(m) {
                let _ = writeln!(s, "usemtl {}", self.materials[m as usize].name);
                current = Some(m);
            }
            let _ = writeln!(s, "f {} {} {}", tri[0] + 1, tri[1] + 1, tri[2] + 1);
        }
        s
    }

    /// The MTL text: for each material `newmtl`, `Kd` and `Ke` (floats in
    /// their shortest round-trip form), no specular part.
    pub fn mtl_text(&self) -> String {
        let mut s = String::new();
        for line in &self.header {
            let _ = writeln!(s, "# {line}");
        }
        for m in &self.materials {
            let _ = writeln!(s, "\nnewmtl {}", m.name);
            let _ = writeln!(s, "Kd {} {} {}", m.kd[0], m.kd[1], m.kd[2]);
            let _ = writeln!(s, "Ke {} {} {}", m.ke[0], m.ke[1], m.ke[2]);
        }
        s
    }

    /// Writes `NAME.obj`, `NAME.mtl` and `NAME.json` into `out_dir`
    /// (created if missing) and returns their paths in that order.
    pub fn write(&self, out_dir: &Path) -> Result<Vec<PathBuf>, GenerateError> {
        std::fs::create_dir_all(out_dir).map_err(|source| GenerateError::Io {
            path: out_dir.to_path_buf(),
            source,
        })?;
        let obj = out_dir.join(format!("{}.obj", self.name));
        let mtl = out_dir.join(format!("{}.mtl", self.name));
        let json = out_dir.join(format!("{}.json", self.name));
        for (path, text) in [(&obj, self.obj_text()), (&mtl, self.mtl_text())] {
            std::fs::write(path, text).map_err(|source| GenerateError::Io {
                path: path.clone(),
                source,
            })?;
        }
        self.config.save(&json)?;
        Ok(vec![obj, mtl, json])
    }
}

/// Builds the bundled scene `name` in memory.
pub fn build(name: &str) -> Result<GeneratedScene, GenerateError> {
    let scene = match name {
        "cornell_box" => cornell::build(),
        "parallel_squares" => analytic::parallel_squares(),
        "perpendicular_squares" => analytic::perpendicular_squares(),
        "coaxial_disks" => analytic::coaxial_disks(),
        "closed_cube" => analytic::closed_cube(),
        "interior" => interior::build(),
        "cornell_panel" => stress::cornell_panel(),
        "cornell_published" => cornell::build_with("cornell_published", 1e9),
        "two_rooms" => stress::two_rooms(),
        "odd_box" => stress::odd_box(),
        "cluttered_room" => stress::cluttered_room(),
        _ => {
            return Err(GenerateError::UnknownScene {
                name: name.to_string(),
                known: [BUNDLED, STRESS].concat().join(", "),
            })
        }
    };
    let scene = scene.map_err(|count| GenerateError::Degenerate {
        name: name.to_string(),
        count,
    })?;
    scene
        .config
        .validate()
        .map_err(|invalid| ConfigError::Invalid {
            path: PathBuf::from(format!("<generated {name}.json>")),
            invalid,
        })?;
    Ok(scene)
}

/// Generates the bundled scene `name` and writes `out_dir/NAME.obj`,
/// `out_dir/NAME.mtl` and `out_dir/NAME.json`, returning those paths.
/// This is what `radiosity generate NAME -o DIR` runs.
pub fn write_bundled(name: &str, out_dir: &Path) -> Result<Vec<PathBuf>, GenerateError> {
    build(name)?.write(out_dir)
}

/// Assembles a `GeneratedScene` from a finished builder.
fn assemble(
    name: &str,
    header: &[&str],
    decimals: usize,
    builder: mesh::MeshBuilder,
    config: SceneConfig,
) -> Result<GeneratedScene, usize> {
    let (mesh, materials) = builder.finish()?;
    Ok(GeneratedScene {
        name: name.to_string(),
        header: header.iter().map(|s| s.to_string()).collect(),
        decimals,
        mesh,
        materials,
        config,
    })
}
