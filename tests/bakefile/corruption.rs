//! Random byte changes, truncations and arbitrary bytes: always detected,
//! never a panic (proptest).

use super::*;

// ---------------------------------------------------------------------------
// Corruption, arbitrary bytes

/// xorshift64*: a tiny deterministic generator for the corruption tests.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn random_byte_changes_are_always_detected() {
    let bytes = encode(&sample()).unwrap();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    // Every single-byte change at every position, with a random new value.
    for at in 0..bytes.len() {
        let mut b = bytes.clone();
        b[at] ^= 1 + rng.below(255) as u8;
        assert!(parse(&b).is_err(), "change at byte {at} went unnoticed");
    }
    // Multi-byte changes.
    for trial in 0..5000 {
        let mut b = bytes.clone();
        for _ in 0..1 + rng.below(8) {
            let at = rng.below(b.len());
            b[at] ^= 1 + rng.below(255) as u8;
        }
        if b != bytes {
            assert!(
                parse(&b).is_err(),
                "trial {trial}: corruption went unnoticed"
            );
        }
    }
}

#[test]
fn reading_a_corrupt_file_names_it() {
    let dir = common::temp_dir("bakefile-corrupt");
    let path = dir.join("corrupt.rad");
    let mut bytes = encode(&sample()).unwrap();
    let n = bytes.len();
    bytes[n - 5] ^= 0xFF;
    std::fs::write(&path, &bytes).unwrap();
    let e = bakefile::read(&path).unwrap_err().to_string();
    assert!(e.starts_with(&path.display().to_string()), "{e}");
    assert!(
        e.contains("section INFO (bake report): checksum mismatch"),
        "{e}"
    );
    let e = bakefile::read(&dir.join("missing.rad"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cannot read bake file") && e.contains("missing.rad"),
        "{e}"
    );
}

/// Proptest case count: `RADIOSITY_FUZZ_CASES` (default 1000).
fn cases() -> u32 {
    std::env::var("RADIOSITY_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary bytes never panic; most are rejected at the magic.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse(&bytes);
    }

    /// Arbitrary bytes behind a valid magic and version reach the deeper
    /// checks, and never panic.
    #[test]
    fn arbitrary_bytes_after_a_valid_header_prefix_never_panic(
        tail in proptest::collection::vec(any::<u8>(), 0..1024),
    ) {
        let mut bytes = b"RADBAKE\0\x01\0\0\0".to_vec();
        bytes.extend_from_slice(&tail);
        prop_assert!(parse(&bytes).is_err());
    }

    /// Structured garbage: a valid file whose table has been rewritten with
    /// arbitrary entries, resealed so that the header checksum passes.
    #[test]
    fn arbitrary_tables_never_panic(
        edits in proptest::collection::vec((0usize..12, 0usize..24, any::<u8>()), 1..6),
    ) {
        let mut bytes = encode(&sample()).unwrap();
        for (i, f, v) in edits {
            bytes[entry(i, f)] = v;
        }
        reseal(&mut bytes);
        let _ = parse(&bytes);
    }

    /// Valid contents of any shape round-trip exactly.
    #[test]
    fn valid_files_round_trip(
        n in 0usize..6,
        rows in proptest::collection::vec((0u32..1000, 1u32..1000), 0..8),
        dense in proptest::collection::vec(any::<u8>(), 0..64),
        seed in any::<u64>(),
    ) {
        let mut rng = Rng(seed | 1);
        let mut bf = sample();
        bf.patches.truncate(n);
        bf.surface_map = SurfaceMap::without_geometry(n);
        bf.samples.position.truncate(n * radiosity::bakefile::surface::SAMPLES_PER_PATCH);
        bf.samples.normal.truncate(n * radiosity::bakefile::surface::SAMPLES_PER_PATCH);
        let mut perm: Vec<u32> = (0..n as u32).collect();
        for i in (1..n).rev() {
            perm.swap(i, rng.below(i + 1));
        }
        bf.permutation = perm;
        bf.codec.n = n as u32;
        bf.codec.dense = dense;
        bf.mesh_map = rows
            .iter()
            .map(|&(p, w)| {
                if n == 0 {
                    [(0, 0.0); 4]
                } else {
                    let a = w as f32 / 1000.0;
                    let q = p % n as u32;
                    if a < 1.0 { [(q, a), ((q + 1) % n as u32, 1.0 - a), (0, 0.0), (0, 0.0)] }
                    else { [(q, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)] }
                }
            })
            .collect();
        let bytes = encode(&bf).unwrap();
        prop_assert_eq!(parse(&bytes).unwrap(), bf);
    }
}
