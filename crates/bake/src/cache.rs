//! Bakes kept for reuse: `render` (and the viewer) given a scene instead of
//! a bake file bake it first, or reuse a bake of the same scene content and
//! options. The cache directory is `$RADIOSITY_CACHE_DIR`, else
//! `$XDG_CACHE_HOME/radiosity`, else `$HOME/.cache/radiosity`; a bake is
//! stored as `NAME-KEY.rad`, `KEY` a hash of the scene's content hash
//! (OBJ, MTL, textures) and the bake's options record, and is reused only
//! when it loads, its stored scene hash equals the scene's, and its
//! options are the ones asked for.

use super::{run, BakeConfig};
use crate::error::BakeError;
use radiosity_bakefile::baked::Baked;
use radiosity_bakefile::hash::Fnv1a64;
use radiosity_bakefile::SceneHash;
use radiosity_core::scene;
use std::path::{Path, PathBuf};

/// The cache directory (module doc), created if missing.
pub fn directory() -> Result<PathBuf, BakeError> {
    let dir = if let Some(d) = std::env::var_os("RADIOSITY_CACHE_DIR") {
        PathBuf::from(d)
    } else if let Some(d) = std::env::var_os("XDG_CACHE_HOME") {
        PathBuf::from(d).join("radiosity")
    } else if let Some(h) = std::env::var_os("HOME") {
        PathBuf::from(h).join(".cache").join("radiosity")
    } else {
        return Err(BakeError::InvalidOption {
            option: "bake cache directory",
            value: "unset".into(),
            expected: "RADIOSITY_CACHE_DIR, XDG_CACHE_HOME or HOME set in the environment".into(),
        });
    };
    std::fs::create_dir_all(&dir).map_err(|source| BakeError::Io {
        what: "create the bake cache directory",
        path: dir.clone(),
        source,
    })?;
    Ok(dir)
}

/// The cached bake's path for `config` (its scene is hashed).
pub fn path_for(config: &BakeConfig, dir: &Path) -> Result<PathBuf, BakeError> {
    let s = scene::load(&config.scene)?;
    let hash = SceneHash::of_scene(&s)?;
    let mut h = Fnv1a64::new();
    h.update(&hash.to_bytes());
    h.update(config.cache_key().as_bytes());
    let stem = config
        .scene
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    Ok(dir.join(format!("{stem}-{:016x}.rad", h.finish())))
}

/// A bake of `config.scene` with `config`'s options: reused from the cache
/// when a matching one is there, else baked (with progress) and stored.
/// Returns the bake file's path and whether it was reused.
pub fn bake_or_reuse(
    config: &BakeConfig,
    progress: &mut dyn FnMut(&str),
) -> Result<(PathBuf, bool), BakeError> {
    let dir = directory()?;
    let path = path_for(config, &dir)?;
    if path.exists() {
        if let Ok(b) = Baked::load(&path) {
            let s = scene::load(&config.scene)?;
            if SceneHash::of_scene(&s)? == b.scene_hash {
                progress(&format!("reusing the bake {}", path.display()));
                return Ok((path, true));
            }
        }
    }
    let mut c = config.clone();
    c.output = Some(path.clone());
    run(&c, progress)?;
    Ok((path, false))
}
