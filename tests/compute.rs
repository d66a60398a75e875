//! The OpenCL layer on PoCL: discovery, device choice, builds with logs,
//! profiling times and allocation limits.

mod common;

use radiosity::core::compute::{self, round_up, Access, DeviceSelection, Gpu};
use radiosity::core::error::ClError;

const SMOKE: &str = r#"
kernel void axpy(float a, global const float* x, global float* y, uint n) {
    uint i = get_global_id(0);
    if (i < n) y[i] = a * x[i] + y[i];
}
"#;

#[test]
fn lists_devices_and_runs_a_kernel() {
    let devices = compute::devices().expect("an OpenCL platform (run scripts/setup)");
    assert!(!devices.is_empty());
    for d in &devices {
        assert!(d.max_mem_alloc_bytes > 0 && d.global_mem_bytes >= d.max_mem_alloc_bytes);
        assert!(d.max_work_group_size >= 1);
    }
    let gpu = common::gpu();
    let program = gpu.build("smoke", SMOKE, "").unwrap();
    let kernel = gpu.kernel(&program, "axpy").unwrap();
    let n = 1000usize;
    let x: Vec<f32> = (0..n).map(|i| i as f32).collect();
    let y: Vec<f32> = (0..n).map(|i| 1.0 - i as f32).collect();
    let xb = gpu.upload("x", &x, Access::ReadOnly).unwrap();
    let yb = gpu.upload("y", &y, Access::ReadWrite).unwrap();
    let local = gpu.local_size(&kernel, 64);
    let (a, n32) = (2.0f32, n as u32);
    let seconds = gpu
        .timed("axpy", || unsafe {
            opencl3::kernel::ExecuteKernel::new(&kernel)
                .set_arg(&a)
                .set_arg(&xb)
                .set_arg(&yb)
                .set_arg(&n32)
                .set_global_work_size(round_up(n, local))
                .set_local_work_size(local)
                .enqueue_nd_range(gpu.queue())
        })
        .unwrap();
    assert!((0.0..10.0).contains(&seconds), "profiling time {seconds}");
    let out = gpu.download("y", &yb, n).unwrap();
    // 2 i + (1 − i) = i + 1 is exact in f32 for i < 2^24.
    for (i, v) in out.iter().enumerate() {
        assert_eq!(*v, i as f32 + 1.0);
    }
}

#[test]
fn build_failure_returns_the_compiler_log() {
    let gpu = common::gpu();
    let err = gpu
        .build(
            "broken.cl",
            "kernel void k(global float* x) { x[0] = undefined_name; }",
            "",
        )
        .unwrap_err();
    let msg = err.to_string();
    assert!(matches!(err, ClError::Build { .. }));
    assert!(
        msg.contains("broken.cl") && msg.contains("undefined_name"),
        "{msg}"
    );
}

#[test]
fn oversized_buffers_are_refused_with_the_limit() {
    let gpu = common::gpu();
    let too_many = (gpu.info().max_mem_alloc_bytes / 4 + 1) as usize;
    let err = gpu
        .buffer::<f32>("huge", too_many, Access::ReadOnly)
        .unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("huge") && msg.contains("CL_DEVICE_MAX_MEM_ALLOC_SIZE"),
        "{msg}"
    );
    let err = gpu
        .check_total("a stage", gpu.info().global_mem_bytes + 1)
        .unwrap_err();
    assert!(err.to_string().contains("CL_DEVICE_GLOBAL_MEM_SIZE"));
}

#[test]
fn device_selection_by_index_and_environment() {
    let n = compute::devices().unwrap().len();
    assert!(Gpu::new(DeviceSelection::Index(0)).is_ok());
    let err = Gpu::new(DeviceSelection::Index(n))
        .err()
        .expect("index past the end");
    assert!(err.to_string().contains(&format!("index {n}")), "{err}");
    assert_eq!(
        DeviceSelection::from_flag_or_env(Some(3)).unwrap(),
        DeviceSelection::Index(3)
    );
    assert_eq!(
        DeviceSelection::from_flag_or_value(None, Some("0")).unwrap(),
        DeviceSelection::Index(0)
    );
    assert_eq!(
        DeviceSelection::from_flag_or_value(None, Some(" ")).unwrap(),
        DeviceSelection::Default
    );
    assert_eq!(
        DeviceSelection::from_flag_or_value(Some(1), Some("0")).unwrap(),
        DeviceSelection::Index(1)
    );
    let err = DeviceSelection::from_flag_or_value(None, Some("gpu")).unwrap_err();
    assert!(
        err.to_string().contains("RADIOSITY_CL_DEVICE") && err.to_string().contains("gpu"),
        "{err}"
    );
}
