//! The shared core: what both phases use. Scene loading and the camera and
//! lights file (with a default made for scenes without one), the patch types, vector helpers, the BVH over the scene's
//! triangles (and its four-wide view for shadow rays), direct light on patches, the OpenCL layer, `.npy` files and the
//! many-sample sums of products the codec's measures run on ([`products`]).
//! Nothing here imports a bake stage, the bake file or the run time.

// NaN-aware tests: `!(x > 0.0)` is true for NaN, which is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bvh;
pub mod bvh4;
pub mod default_view;
pub mod direct;
pub mod error;
pub mod light;
pub mod math;
pub mod npy;
pub mod objects;
pub mod patch;
pub mod permutation;
pub mod pfm;
pub mod polygon;
pub mod products;
pub mod scene;
pub mod scene_config;
pub mod sh;
pub mod sky;
