//! The FMA peak kernel (`crates/bake/kernels/peak.cl`, host
//! `crates/bake/src/peak.rs`) against its CPU reference, `peak::reference`:
//! the same fused multiply-adds in the same order, each exactly rounded,
//! and the lanes summed in the same order with contraction off, so every
//! work-item's output agrees bit for bit (tolerance zero).

mod common;

use radiosity::bake::peak;

#[test]
fn peak_kernel_matches_its_reference_and_reports_a_rate() {
    let g = common::gpu();
    let p = peak::measure(&g, 1000, 2).expect("measuring the peak");
    assert!(
        p.gflops.is_finite() && p.gflops > 0.0,
        "{} GFLOP/s",
        p.gflops
    );
    assert_eq!(p.outputs.len(), p.work_items);
    for (gid, &got) in p.outputs.iter().enumerate() {
        let want = peak::reference(gid, p.vector_width, p.iterations);
        assert_eq!(
            got.to_bits(),
            want.to_bits(),
            "work-item {gid}: {got} against {want}"
        );
    }
    // Not vacuous: the chains moved from their starts towards 1.
    let lanes = (peak::CHAINS * p.vector_width) as f32;
    assert!((p.outputs[0] / lanes - 1.0).abs() < 0.7);
}
