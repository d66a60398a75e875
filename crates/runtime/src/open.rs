//! Opening a bake for the run time: the bake file, the scene it was baked
//! from (for shadow rays, textures and the surface map's triangles), and
//! the check that the two belong together. This is what an application
//! embedding the run time calls first (`docs/library.md`, "Using the run time from
//! Rust"; `examples/embed.rs`); `radiosity render` and `view` call it too.
//!
//! The scene is found where the bake file says (its stored path, relative
//! to the bake file), unless the caller names it. The bake stores a hash of
//! the scene's files (OBJ, MTL, textures: [`SceneHash`]); a scene whose
//! files hash differently is an error naming what changed, since the
//! surface map indexes the scene's triangles and a changed OBJ would be
//! lit through the wrong patches without a word.

use super::{Runtime, RuntimeOptions};
use radiosity_bakefile::baked::{resolve_scene_path, Baked, LoadError};
use radiosity_bakefile::{BakeFileError, SceneHash};
use radiosity_core::error::SceneError;
use radiosity_core::scene::{self, Scene};
use std::path::{Path, PathBuf};

/// Why a bake cannot be opened for the run time.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The bake file is missing, truncated, corrupt or of another version.
    #[error(transparent)]
    Bake(#[from] LoadError),
    /// The scene (as the bake names it, or as given) cannot be loaded.
    #[error("loading the scene {path} that {bake} was baked from")]
    Scene {
        bake: PathBuf,
        path: PathBuf,
        #[source]
        source: SceneError,
    },
    /// The scene's files cannot be read to be hashed.
    #[error(transparent)]
    Hash(#[from] BakeFileError),
    /// The scene is not the one the bake was made from.
    #[error("{bake} was baked from a different scene than {scene} ({}): bake it again", changed.join(", "))]
    SceneChanged {
        bake: PathBuf,
        scene: PathBuf,
        /// What differs: "obj", "mtl", "textures".
        changed: Vec<&'static str>,
    },
}

/// The bake at `bake` and its scene (at `scene`, else where the bake file
/// names it), checked to be the scene it was baked from; with the scene's
/// path. The scene's load warnings are in [`Scene::warnings`] for the
/// caller to show.
pub fn load_checked(
    bake: &Path,
    scene: Option<&Path>,
) -> Result<(Baked, Scene, PathBuf), OpenError> {
    let baked = Baked::load(bake)?;
    let path = scene.map_or_else(
        || resolve_scene_path(bake, &baked.info.scene),
        Path::to_path_buf,
    );
    let loaded = scene::load(&path).map_err(|source| OpenError::Scene {
        bake: bake.to_path_buf(),
        path: path.clone(),
        source,
    })?;
    let changed = baked.scene_hash.differences(&SceneHash::of_scene(&loaded)?);
    if !changed.is_empty() {
        return Err(OpenError::SceneChanged {
            bake: bake.to_path_buf(),
            scene: path,
            changed,
        });
    }
    Ok((baked, loaded, path))
}

impl Runtime {
    /// The run time of the bake at `bake` ([`load_checked`]: its scene at
    /// `scene`, else where the bake names it, checked to be the one it was
    /// baked from).
    pub fn open(
        bake: &Path,
        scene: Option<&Path>,
        options: RuntimeOptions,
    ) -> Result<Runtime, OpenError> {
        let (baked, scene, _) = load_checked(bake, scene)?;
        Ok(Runtime::new(baked, scene, options))
    }

    /// The first front face of the scene on the ray `origin + t direction`,
    /// `t > 0` (within the scene's reach): its triangle (index in the scene
    /// as loaded) and the point hit. A back face (the side opposite the
    /// winding, which receives and emits nothing) ends the ray with `None`,
    /// as it is black in the renderers; in a two-sided bake its coincident
    /// twin faces the ray and is returned. A zero or non-finite direction
    /// or origin meets nothing.
    pub fn first_hit(&self, origin: [f64; 3], direction: [f64; 3]) -> Option<(usize, [f64; 3])> {
        use radiosity_core::math::{add, dot, normalize, scale};
        let far = 4.0 * self.direct.far();
        let d = normalize(direction);
        if !(d.iter().chain(&origin).all(|v| v.is_finite())) {
            return None; // a zero or non-finite direction, or origin
        }
        let (k, t) = self.direct.closest_hit(origin, scale(d, far))?;
        let mut tri = self.direct.bvh().order[k as usize] as usize;
        if dot(self.scene.triangle_normal(tri), d) >= 0.0 {
            // The coincident back side faces the ray, if there is one.
            tri = self.scene.twin(tri)?;
        }
        Some((tri, add(origin, scale(d, t * far))))
    }

    /// The indirect irradiance `H(x)` of the last frame at the point `x`
    /// of the scene's triangle `triangle` (its index in the scene as
    /// loaded: the OBJ's faces in order, polygons cut into triangles), from
    /// the surface map ([`super::surface`]): what the renderers shade
    /// with. `[0; 3]` where no patch lights the triangle. The radiance
    /// leaving `x` is `ρ(x)/π · (D(x) + H(x)) + Le`.
    pub fn indirect_at(&self, triangle: usize, x: [f32; 3]) -> [f32; 3] {
        let (w, _) = super::surface::weights(&self.baked.surface_map, triangle, x);
        super::surface::apply(&w, &self.h)
    }
}
