//! The scene as the rays from the real surfaces see it, and what a ray
//! meets: the BVH of the original triangles, the cover rule, the piece
//! lookup that credits a hit to its patch (`Tracer`), and where the
//! nearest hits are found, on the CPU or on an OpenCL device
//! ([`ray_gpu`], `crate::trace`). The form factors' rays
//! (`super::rays`), the near field and the probes share it.

use super::RayDevice;
use crate::compute::{Backend, Gpu};
use crate::error::BakeError;
use crate::pieces::PieceLookup;
use crate::pieces::{self, PieceGeo, CUT_INSET};
use crate::trace::{DeviceTracer, BATCH_RAYS};
use crate::voxelize::{Cover, Voxelization};
use radiosity_core::bvh::Bvh;
use radiosity_core::bvh4::Bvh4;
use radiosity_core::math::{add, dot, norm, normalize, scale, sub};
use radiosity_core::scene::Scene;

/// The device the rays are traced on by `choice` ([`RayDevice`]), when
/// `backend` has one and it can (it has `cl_khr_fp64`); `None`: the CPU.
pub fn ray_gpu<'g>(backend: &Backend<'g>, choice: RayDevice) -> Option<&'g Gpu> {
    let Backend::OpenCl(g) = backend else {
        return None;
    };
    let info = g.info();
    let wanted = match choice {
        RayDevice::Cpu => false,
        RayDevice::Device => true,
        // A CPU device is the same cores the native traversal (AVX) uses
        // faster: `bench form-factors` measures both.
        RayDevice::Auto => info.kind != "CPU",
    };
    (wanted && info.fp64).then_some(*g)
}

/// Where the rays are traced: on `backend`'s device through
/// [`crate::trace::DeviceTracer`] when `choice` allows it and the device
/// can (it has `cl_khr_fp64`), else on the CPU; and the stage's backend
/// as the report names it.
pub(crate) fn device_tracer<'g>(
    backend: &Backend<'g>,
    rs: &RayScene,
    choice: RayDevice,
) -> Result<(Option<DeviceTracer<'g>>, String), BakeError> {
    const CPU: &str = "rays from the real surfaces (CPU, f64)";
    let gpu = match backend {
        Backend::OpenCl(g) => *g,
        Backend::Cpu => return Ok((None, CPU.into())),
    };
    let info = gpu.info();
    if ray_gpu(backend, choice).is_none() {
        return Ok((
            None,
            format!(
                "{CPU}; the OpenCL device {} left to the other stages",
                info.name
            ),
        ));
    }
    if !info.fp64 {
        return Ok((
            None,
            format!("{CPU}: the OpenCL device {} lacks cl_khr_fp64", info.name),
        ));
    }
    let tracer = DeviceTracer::new(gpu, &rs.bvh, &rs.bvh4, BATCH_RAYS)?;
    Ok((
        Some(tracer),
        format!(
            "rays from the real surfaces (OpenCL traversal on {} ({}, {}), f64)",
            info.name, info.kind, info.platform
        ),
    ))
}

/// What a ray from a patch's real surface meets ([`Tracer::trace`]).
pub(crate) enum Hit {
    /// Nothing: it left the scene.
    Escaped,
    /// The back of a surface.
    Back,
    /// A front face (scene triangle `tri`) whose piece no patch owns.
    Unowned { tri: u32 },
    /// A front face (scene triangle `tri`) at `y` of a piece of
    /// voxelization patch `patch`.
    Owned { patch: u32, y: [f64; 3], tri: u32 },
}

/// The scene as the rays see it: the original triangles' BVH (shifted to
/// the grid's centre, [`super::shift_of`]), their normals (for the cover
/// rule), the piece lookup, and the origins' lift along the normal and the
/// rays' length: 1e-4 and 4 times the scene's largest extent. Built once
/// per stage that casts rays from the real surfaces.
pub(crate) struct RayScene {
    pub bvh: Bvh,
    /// Its four-wide view, which the rays traverse ([`Bvh4::closest_hit`]:
    /// the binary traversal's nearest hit, four boxes per test).
    pub bvh4: Bvh4,
    normals: Vec<[f64; 3]>,
    lookup: PieceLookup,
    shift: [f64; 3],
    offset: f64,
    far: f64,
}

impl RayScene {
    pub(crate) fn new(scene: &Scene, vox: &Voxelization) -> RayScene {
        let shift = super::shift_of(&vox.grid);
        let (lo, hi) = scene.bounds();
        let extent = (0..3)
            .map(|a| (hi[a] - lo[a]) as f64)
            .fold(0.0, f64::max)
            .max(1e-30);
        let bvh = Bvh::build(&scene.positions, &scene.triangles, shift);
        RayScene {
            bvh4: Bvh4::build(&bvh),
            bvh,
            normals: scene.triangle_normals(),
            lookup: PieceLookup::new(vox, scene.triangles.len()),
            shift,
            offset: 1e-4 * extent,
            far: 4.0 * extent,
        }
    }

    /// The covered-point rule over this BVH ([`Cover`]).
    pub(crate) fn cover<'a>(&'a self, scene: &Scene, vox: &Voxelization) -> Cover<'a> {
        Cover::new(scene, &vox.grid, &self.bvh, &self.normals)
    }
}

/// A [`RayScene`] with its cover rule and the voxelization whose pieces
/// own what the rays meet.
pub(crate) struct Tracer<'a> {
    pub rays: &'a RayScene,
    pub cover: &'a Cover<'a>,
    pub vox: &'a Voxelization,
}

impl Tracer<'_> {
    /// The ray from `x` (world, on a surface of normal `n`) along `d`.
    pub(crate) fn trace(&self, x: [f64; 3], n: [f64; 3], d: [f64; 3]) -> Hit {
        let (o, seg) = self.segment(x, n);
        let rs = self.rays;
        self.resolve(o, d, rs.bvh4.closest_hit(&rs.bvh, o, scale(d, rs.far)), seg)
    }

    /// Where the ray from `x` (on a surface of normal `n`) starts in the
    /// BVH's shifted frame, lifted off the surface, and the rays' length:
    /// the segment is `o + t · far · d`, `t ∈ (0, 1]`.
    pub(crate) fn segment(&self, x: [f64; 3], n: [f64; 3]) -> ([f64; 3], f64) {
        let rs = self.rays;
        (sub(add(x, scale(n, rs.offset)), rs.shift), rs.far)
    }

    /// What the segment from `o` (shifted frame, [`Tracer::segment`]) along
    /// `d`, of length `far`, meets, given its nearest hit `(leaf, t)` (the
    /// CPU's [`Bvh4::closest_hit`] or the device's, `crate::trace`).
    pub(crate) fn resolve(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        hit: Option<(u32, f64)>,
        far: f64,
    ) -> Hit {
        let rs = self.rays;
        let Some((mut leaf, tp)) = hit else {
            return Hit::Escaped;
        };
        if dot(geo_normal(&rs.bvh, leaf), d) >= 0.0 {
            // The back of a surface, unless a front face coincides with it
            // (a two-sided surface modelled as two triangles, or
            // `Scene::with_back_sides`): then that front face is what the
            // ray meets (the cover rule's).
            match self.cover.front_at(o, d, tp * far, u32::MAX) {
                Some(front) => leaf = front,
                None => return Hit::Back,
            }
        }
        let tri = rs.bvh.order[leaf as usize] as usize;
        let y = add(add(o, scale(d, tp * far)), rs.shift);
        // The part of a cut piece is the one on the side the ray came from
        // when it lands within CUT_INSET voxels of the cut: a ray can slip
        // through the f32 rounding at the foot of the wall that cut it.
        let back = scale(
            d,
            -CUT_INSET as f64 * self.vox.grid.size / norm(d).max(1e-300),
        );
        match rs
            .lookup
            .find_from(self.vox, tri, y, back)
            .and_then(|p| self.vox.pieces[p].patch)
        {
            Some(patch) => Hit::Owned {
                patch,
                y,
                tri: tri as u32,
            },
            None => Hit::Unowned { tri: tri as u32 },
        }
    }
}

/// The unit normal of a BVH triangle (its winding), from its stored f32
/// vertices.
pub(crate) fn geo_normal(bvh: &Bvh, leaf: u32) -> [f64; 3] {
    let t = &bvh.tris[leaf as usize];
    let p = |v: [f32; 3]| v.map(f64::from);
    let nn = radiosity_core::math::cross(sub(p(t.v1), p(t.v0)), sub(p(t.v2), p(t.v0)));
    normalize(nn)
}

/// Runs `f` with a [`Tracer`] over `scene` as `vox` cuts it, the pieces'
/// geometry and each patch's pieces (voxelization order): what every stage
/// casting rays from the real surfaces sets up first.
pub(crate) fn with_tracer<R>(
    scene: &Scene,
    vox: &Voxelization,
    f: impl FnOnce(&Tracer, &[PieceGeo], &[Vec<usize>]) -> R,
) -> R {
    let geo = pieces::geometry(scene, vox);
    let by_patch = pieces::by_patch(vox);
    let rs = RayScene::new(scene, vox);
    let cover = rs.cover(scene, vox);
    let tracer = Tracer {
        rays: &rs,
        cover: &cover,
        vox,
    };
    f(&tracer, &geo, &by_patch)
}
