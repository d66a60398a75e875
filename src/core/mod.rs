//! The shared core: what both phases use. Scene loading and the camera and
//! lights file (with a default made for scenes without one), the patch types, vector helpers, the BVH over the scene's
//! triangles (and its four-wide view for shadow rays), direct light on patches, the OpenCL layer and `.npy` files.
//! Nothing here imports a bake stage, the bake file or the run time.

pub mod bvh;
pub mod bvh4;
pub mod compute;
pub mod default_view;
pub mod direct;
pub mod error;
pub mod light;
pub mod math;
pub mod npy;
pub mod patch;
pub mod permutation;
pub mod polygon;
pub mod scene;
pub mod scene_config;
