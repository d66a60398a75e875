//! The ray kernel (`crates/bake/kernels/trace.cl`, host
//! `crates/bake/src/trace.rs`) against its CPU reference,
//! `Bvh4::closest_hit`: the kernel follows the reference in f64 with
//! contraction off, so the tolerance is zero — the same triangle and the
//! same `t` bit for bit for every segment. Then the stages that trace on
//! it (the rays form factors, the near field) give the same counts on the
//! device as on the CPU, on generated scenes that are not kind (one big
//! quad per wall, a 1 cm wall the grid cuts into slivers, a box wound the
//! wrong way, a tilted plate; millimetres to kilometres) and on Sponza at
//! 1,000 patches, all on PoCL here.

mod common;

use common::{block, box_inside, gpu, quad, write_quads, Quad};
use radiosity::bake::form_factor::{self, FormFactorOptions, FormFactors, RayDevice};
use radiosity::bake::trace::DeviceTracer;
use radiosity::bake::voxelize::{self, Resolution, Voxelization};
use radiosity::bake::{near_field, surface_map};
use radiosity::core::bvh::Bvh;
use radiosity::core::bvh4::Bvh4;
use radiosity::core::compute::Backend;
use radiosity::core::math::SplitMix64;
use radiosity::core::scene::{self, Scene};

/// A room `s` metres a unit (1e-3: millimetres drawn in metres' numbers'
/// place, 1e3: kilometres): walls one quad each, a 1 cm partition placed
/// off the grid (slivers where the voxels cut it), a closed box wound
/// inside out, and a tilted plate.
fn hostile(s: f64, tag: &str) -> Scene {
    let sc = |p: [f64; 3]| p.map(|x| x * s);
    let mut quads: Vec<Quad> = box_inside(sc([0.0; 3]), sc([4.0, 2.5, 3.0]), [0.7; 3]);
    quads.extend(block(
        sc([1.7003, 0.0, 0.31]),
        sc([1.7103, 1.83, 2.17]),
        [0.6, 0.3, 0.3],
    ));
    quads.extend(
        block(
            sc([2.61, 0.0, 1.03]),
            sc([3.13, 0.41, 1.57]),
            [0.3, 0.6, 0.3],
        )
        .into_iter()
        .map(|mut q| {
            q.corners.reverse();
            q
        }),
    );
    let n = [0.3f64, 0.8, 0.52];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let n = n.map(|x| x / len);
    let u = {
        let a = [n[2], 0.0, -n[0]];
        let l = (a[0] * a[0] + a[2] * a[2]).sqrt();
        a.map(|x| x / l)
    };
    let v = [
        n[1] * u[2] - n[2] * u[1],
        n[2] * u[0] - n[0] * u[2],
        n[0] * u[1] - n[1] * u[0],
    ];
    quads.push(quad(
        sc([0.9, 1.1, 2.2]),
        u,
        v,
        0.37 * s,
        0.23 * s,
        [0.5; 3],
    ));
    scene::load(&write_quads(tag, &quads)).expect("loading the generated scene")
}

const SCALES: [f64; 3] = [1e-3, 1.0, 1e3];

/// Random segments through the scene: origins inside its bounds (some on
/// vertices, some on the walls' planes), directions random or along an
/// axis (zero components: infinite inverses), four times the extent long.
fn segments(scene: &Scene, shift: [f64; 3], count: usize) -> (Vec<f64>, Vec<f64>) {
    let (lo, hi) = scene.bounds();
    let extent = (0..3).map(|a| (hi[a] - lo[a]) as f64).fold(0.0, f64::max);
    let mut rng = SplitMix64::new(41);
    let (mut o, mut d) = (Vec::new(), Vec::new());
    for k in 0..count {
        let mut p: [f64; 3] =
            std::array::from_fn(|a| lo[a] as f64 + rng.uniform() * (hi[a] - lo[a]) as f64);
        match k % 5 {
            // On a vertex.
            0 => {
                let v = scene.positions[k % scene.positions.len()];
                p = v.map(f64::from);
            }
            // On a wall's plane.
            1 => p[k % 3] = lo[k % 3] as f64,
            _ => {}
        }
        let dir: [f64; 3] = if k % 7 == 0 {
            let mut a = [0.0; 3];
            a[k % 3] = if k % 2 == 0 { 1.0 } else { -1.0 };
            a
        } else {
            let z = 2.0 * rng.uniform() - 1.0;
            let phi = 2.0 * std::f64::consts::PI * rng.uniform();
            let r = (1.0 - z * z).max(0.0).sqrt();
            [r * phi.cos(), r * phi.sin(), z]
        };
        o.extend((0..3).map(|a| p[a] - shift[a]));
        d.extend(dir.map(|x| x * 4.0 * extent));
    }
    (o, d)
}

/// Every segment's nearest hit on the device equals the CPU's, bit for
/// bit, on the AVX and the portable traversal alike.
#[test]
fn kernel_nearest_hits_equal_the_cpu_bit_for_bit() {
    let g = gpu();
    for s in SCALES {
        let scene = hostile(s, "trace-bits");
        let (lo, hi) = scene.bounds();
        let shift: [f64; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]) as f64);
        let bvh = Bvh::build(&scene.positions, &scene.triangles, shift);
        let bvh4 = Bvh4::build(&bvh);
        let portable = bvh4.clone().portable();
        let (o, d) = segments(&scene, shift, 20_000);
        // A small batch capacity so that several launches are checked.
        let mut tracer = DeviceTracer::new(&g, &bvh, &bvh4, 7_000).expect("the ray kernel");
        let got = tracer.closest(&o, &d).expect("tracing");
        assert_eq!(tracer.rays, 20_000);
        let mut hits = 0;
        for (k, hit) in got.iter().enumerate() {
            let (ok, dk) = (
                [o[3 * k], o[3 * k + 1], o[3 * k + 2]],
                [d[3 * k], d[3 * k + 1], d[3 * k + 2]],
            );
            let want = bvh4.closest_hit(&bvh, ok, dk);
            let bits = |h: Option<(u32, f64)>| h.map(|(l, t)| (l, t.to_bits()));
            assert_eq!(
                bits(*hit),
                bits(want),
                "scale {s}: segment {k} from {ok:?} along {dk:?}"
            );
            assert_eq!(bits(want), bits(portable.closest_hit(&bvh, ok, dk)));
            hits += usize::from(hit.is_some());
        }
        // Not vacuous: the room is closed, so a segment misses only when it
        // starts on the outer boundary (a fifth start on a wall's plane,
        // others on corner vertices) and leaves: 16,417 of 20,000 hit.
        assert!(
            hits > 15_000,
            "scale {s}: only {hits} of 20000 segments hit"
        );
    }
}

fn form_factors_on(scene: &Scene, vox: &Voxelization, backend: &Backend, rays: u32) -> FormFactors {
    let options = FormFactorOptions {
        rays_per_patch: rays,
        ray_device: RayDevice::Device,
        ..Default::default()
    };
    form_factor::of_voxelization(scene, vox, &options, backend, &mut |_, _| {})
        .expect("form factors")
}

/// The device's rays give the CPU's form factors exactly: the same
/// patches kept, the same matrix bit for bit, the same counts of rays by
/// what they met and the same sky.
fn assert_same(a: &FormFactors, b: &FormFactors, what: &str) {
    assert_eq!(a.kept, b.kept, "{what}: kept patches");
    assert_eq!(a.n, b.n);
    let (sa, sb) = (&a.stats, &b.stats);
    assert_eq!(
        (
            sa.rays_cast,
            sa.rays_escaped,
            sa.rays_back_face,
            sa.rays_unowned,
            sa.rays_covered
        ),
        (
            sb.rays_cast,
            sb.rays_escaped,
            sb.rays_back_face,
            sb.rays_unowned,
            sb.rays_covered
        ),
        "{what}: ray counts"
    );
    let differ =
        a.f.iter()
            .zip(&b.f)
            .filter(|(x, y)| x.to_bits() != y.to_bits())
            .count();
    assert_eq!(differ, 0, "{what}: {differ} entries differ");
    assert_eq!(a.sky, b.sky, "{what}: sky");
    assert!(
        sa.backend.contains("OpenCL traversal"),
        "{what}: {}",
        sa.backend
    );
    assert!(sb.backend.contains("CPU"), "{what}: {}", sb.backend);
}

#[test]
fn form_factors_and_near_field_on_the_device_equal_the_cpus() {
    let g = gpu();
    for s in SCALES {
        let scene = hostile(s, "trace-ff");
        let vox = voxelize::voxelize_at(&scene, 0.25 * s, &Backend::Cpu).expect("voxelizing");
        assert!(vox.patches.len() > 300, "{} patches", vox.patches.len());
        let on_device = form_factors_on(&scene, &vox, &Backend::OpenCl(&g), 2048);
        let on_cpu = form_factors_on(&scene, &vox, &Backend::Cpu, 2048);
        assert_same(&on_device, &on_cpu, &format!("scale {s}"));
        // Not vacuous: the rays met back faces (the box wound inside
        // out) and most met patches.
        assert!(on_cpu.stats.rays_back_face > 0);
        assert!(on_cpu.stats.front_fraction > 0.8);

        // The near field's rays, through the same kernel.
        let n = on_cpu.n;
        let mut patch_index_of = vec![None; vox.patches.len()];
        for (m, &v) in on_cpu.kept.iter().enumerate() {
            patch_index_of[v] = Some(m as u32);
        }
        let (_, samples, _) =
            surface_map::build(&scene, &vox, &patch_index_of, n).expect("surface map");
        let near = |backend: &Backend| {
            near_field::build(
                &scene,
                &vox,
                &patch_index_of,
                &samples,
                n,
                1024,
                near_field::MIN_FORM_FACTOR,
                backend,
                RayDevice::Device,
                &mut |_, _| {},
            )
            .expect("near field")
            .0
        };
        let (a, b) = (near(&Backend::OpenCl(&g)), near(&Backend::Cpu));
        assert!(!b.links.is_empty());
        assert_eq!(a.to_bytes(), b.to_bytes(), "scale {s}: near field");
    }
}

/// Sponza at about 1,000 patches (1,024 rays a patch: the equality holds
/// ray by ray, whatever their number).
#[test]
fn sponza_form_factors_on_the_device_equal_the_cpus() {
    let g = gpu();
    let scene = scene::load(&common::sponza()).expect("loading Sponza");
    let vox = voxelize::voxelize_counting(
        &scene,
        Resolution::Patches(1000),
        &Backend::Cpu,
        // The bake's count: the patches that see another surface.
        &|v: &Voxelization| form_factor::rays::seeing_patches(&scene, v, 256),
    )
    .expect("voxelizing");
    let on_device = form_factors_on(&scene, &vox, &Backend::OpenCl(&g), 1024);
    let on_cpu = form_factors_on(&scene, &vox, &Backend::Cpu, 1024);
    assert!(on_cpu.n > 700, "{} patches kept", on_cpu.n);
    assert_same(&on_device, &on_cpu, "Sponza");
}
