//! glTF 2.0 scenes (crates/core/src/scene/gltf): files written here, by hand with
//! a small builder (node transforms, a mirror, strips and fans, texture
//! coordinate sets and transforms, lights and a camera, broken files) or by
//! `scripts/obj2gltf.py` (an independent Python converter) from the OBJ
//! scenes, whose bakes must then match the OBJ's. Expected values are
//! computed by hand from the spec: transforms, photometric units
//! (683 lm/W), the emissive radiance as exitance (`π L`), the texture
//! transform's example.
#[path = "../common/mod.rs"]
mod common;

mod bad;
mod builder;
mod geometry;
mod materials;
mod view;
