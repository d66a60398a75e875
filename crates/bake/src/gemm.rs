//! The OpenCL matrix product behind the transfer stage ([`crate::transfer`]):
//! `C = D + A·B` or `C = A·B` for square row-major f32 matrices on the device,
//! tiled in local memory, register-blocked and vectorised
//! (`crates/bake/kernels/gemm.cl`), with all-zero tiles of the operands skipped.
//!
//! **Padding.** Matrices live on the device padded with zeros to
//! `N = round_up(n, tile)`, so the kernel needs no bounds checks; zero
//! padding rows and columns keep every product's padding zero, and the host
//! crops on download. [`DeviceMatrix`] holds the padded buffer.
//!
//! **Zero tiles.** Every device matrix carries one flag per `tile × tile`
//! tile: whether it holds a non-zero entry. Uploads compute them with the
//! `tile_flags` kernel; a product computes its output's flags in its
//! epilogue, for free. The kernel skips the K blocks whose A or B tile is
//! zero; skipped blocks contribute exact zeros, so the result is bitwise the
//! same as without skipping. Closed rooms make the transfer matrices
//! block-sparse, and zero-albedo patches make whole tile columns zero.
//!
//! **Configuration** ([`GemmConfig::for_device`]). One kernel source serves
//! GPUs and CPUs through compile-time parameters:
//! - on a GPU: 64 × 64 tiles, 16 × 16 work-items each computing a 4 × 4
//!   micro-tile as float4 vectors, the A block stored transposed in local
//!   memory (32 KiB of local memory); smaller tiles when the device's
//!   work-group size or local memory is smaller;
//! - on a CPU (PoCL): a work-group runs on one thread and its work-items run
//!   one after the other, so more work-items add no parallelism, only
//!   context switches; the parallelism is across work-groups. The work-group
//!   is one work-item owning a 256 × 256 tile (128 × 128 for smaller n,
//!   where 256 would pad too much) and looping over 8 × 32 micro-tiles held
//!   in 16 float16 accumulators (on AVX-512: 16 of the 32 zmm registers, one
//!   broadcast and two vector loads per 16 FMAs, the register block of
//!   BLIS's Skylake-X kernel); the local-memory blocks (2 × 256 KiB) are
//!   the copied panels that stay in L2. Measured at 0.9–1.0 of faer's f32
//!   product under PoCL here (docs/transfer.md).
//!
//! The CPU reference is faer's matrix product ([`reference_product`], f64);
//! `bench_gemm` measures GFLOP/s against faer's f32 product in the same
//! run.

use crate::compute::{round_up, Access, DeviceInfo, Gpu};
use crate::error::BakeError;
use opencl3::kernel::{ExecuteKernel, Kernel};
use opencl3::memory::Buffer;
use serde::Serialize;

/// The kernel source, embedded.
pub const KERNEL_SOURCE: &str = include_str!("../kernels/gemm.cl");

/// How the A block is laid out in local memory (`LAYOUT` in
/// `crates/bake/kernels/gemm.cl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Layout {
    /// As in global memory: a plain vector copy (CPUs).
    RowMajor = 0,
    /// Transposed: a work-item's MR values of A at one k are adjacent, so a
    /// GPU warp reads them without bank conflicts (GPUs).
    ATransposed = 1,
}

/// Compile-time parameters of the `gemm` kernel (see `crates/bake/kernels/gemm.cl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct GemmConfig {
    /// Work-group tile of C, K block, padding multiple and zero-tile
    /// granularity (`TS`).
    pub tile: usize,
    /// Rows and columns of a work-item's micro-tile (`MR`, `NR`).
    pub mr: usize,
    pub nr: usize,
    /// Floats per vector (`VW`): 4, 8 or 16.
    pub vector: usize,
    /// Local size `[LX, LY]`.
    pub local: [usize; 2],
    /// Layout of the A block in local memory (`LAYOUT`).
    pub layout: Layout,
    /// Unroll factor of the K loop (`KU`).
    pub unroll: usize,
    /// The K sub-block held in local memory (`KB`): the tile, or on the
    /// GPU forms with one micro-tile per work-item, a divisor of it (the
    /// results are the same bit for bit; `kernels/gemm.cl`).
    pub kb: usize,
}

impl GemmConfig {
    /// The configuration for a device and matrix size `n`: the GPU form
    /// when the device is a GPU, else the CPU form, each shrunk until it
    /// fits the device's work-group size and local memory.
    /// `native_float_width` is the device's
    /// `CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT` (16 on AVX-512 under PoCL, 8 on
    /// AVX2).
    pub fn for_device(info: &DeviceInfo, native_float_width: u32, n: usize) -> GemmConfig {
        if info.kind == "GPU" {
            // The wide form first (module doc), then 16 × 16 work-items of
            // 4 × 4 outputs on a 64 × 64 tile; 8 × 8 of 4 × 4 on 32 × 32;
            // 4 × 4 of 4 × 4 on 16 × 16.
            let narrow = [(64, 16), (32, 8), (16, 4)].map(|(tile, l)| GemmConfig {
                tile,
                mr: 4,
                nr: 4,
                vector: 4,
                local: [l, l],
                layout: Layout::ATransposed,
                unroll: 8,
                kb: tile,
            });
            return GemmConfig::gpu_wide()
                .into_iter()
                .chain(narrow)
                .find(|c| c.fits(info))
                .unwrap_or_else(GemmConfig::minimal);
        }
        let vector = match native_float_width {
            w if w >= 16 => 16,
            w if w >= 8 => 8,
            _ => 4,
        };
        // Registers: MR × NR / VW accumulators + NR / VW B vectors + one
        // broadcast. 8 × 32 with float16 is 19 of AVX-512's 32 registers;
        // 4 × 16 with float8 is 11 of AVX2's 16.
        let mr = if vector == 16 { 8 } else { 4 };
        // The tile: larger tiles amortise the block copies and the running
        // totals' updates over more arithmetic (measured under PoCL on
        // AVX-512, one thread against faer's: 256 → 0.85-0.95 of faer,
        // 128 → 0.7), but pad n further. Take the least estimated time
        // padded³ / speed among the tiles that fit and leave at least two
        // work-groups per compute unit.
        let speed = |tile: usize| match tile {
            256 => 1.25,
            128 => 1.0,
            64 => 0.7,
            _ => 0.4,
        };
        let candidates: Vec<GemmConfig> = [256, 128, 64, 32]
            .into_iter()
            .map(|tile| GemmConfig {
                tile,
                mr,
                nr: 2 * vector,
                vector,
                local: [1, 1],
                layout: Layout::RowMajor,
                unroll: 4,
                kb: tile,
            })
            .filter(|c| c.fits(info))
            .collect();
        let busy = |c: &GemmConfig| {
            (round_up(n.max(1), c.tile) / c.tile).pow(2) >= 2 * info.compute_units as usize
        };
        let cost = |c: &GemmConfig| (round_up(n.max(1), c.tile) as f64).powi(3) / speed(c.tile);
        candidates
            .iter()
            .filter(|c| busy(c))
            .chain(candidates.last())
            .min_by(|a, b| cost(a).total_cmp(&cost(b)))
            .copied()
            .unwrap_or_else(GemmConfig::minimal)
    }

    /// The smallest configuration, for devices that fit nothing else.
    fn minimal() -> GemmConfig {
        GemmConfig {
            tile: 4,
            mr: 4,
            nr: 4,
            vector: 4,
            local: [1, 1],
            layout: Layout::RowMajor,
            unroll: 1,
            kb: 4,
        }
    }

    /// The GPU forms on 128 × 128 tiles (module doc), fastest first on
    /// paper: 16 × 16 work-items of 8 × 8 outputs with K sub-blocks of 16
    /// (CLBlast's tuned NVIDIA shape) or 32, and 16 × 32 work-items of
    /// 4 × 8. They share the tile, so they give the same bits and
    /// [`Gemm::new`] may pick among them by time.
    pub fn gpu_wide() -> [GemmConfig; 3] {
        let base = GemmConfig {
            tile: 128,
            mr: 8,
            nr: 8,
            vector: 4,
            local: [16, 16],
            layout: Layout::ATransposed,
            unroll: 8,
            kb: 16,
        };
        [
            base,
            GemmConfig { kb: 32, ..base },
            GemmConfig {
                mr: 4,
                local: [16, 32],
                ..base
            },
        ]
    }

    /// Local memory the kernel declares: the `tile × kb` A block and `kb ×
    /// tile` B block plus the epilogue's reduction arrays.
    pub fn local_bytes(&self) -> u64 {
        (2 * self.tile * self.kb * 4 + self.work_items() * 8) as u64
    }

    pub fn work_items(&self) -> usize {
        self.local[0] * self.local[1]
    }

    fn fits(&self, info: &DeviceInfo) -> bool {
        self.work_items() <= info.max_work_group_size && self.local_bytes() <= info.local_mem_bytes
    }

    /// Checks the divisibility rules of the kernel and the device's limits.
    pub fn validate(&self, info: &DeviceInfo) -> Result<(), BakeError> {
        let [lx, ly] = self.local;
        let ok = [4, 8, 16].contains(&self.vector)
            && self.mr > 0
            && self.nr > 0
            && lx > 0
            && ly > 0
            && self.unroll > 0
            && self.nr.is_multiple_of(self.vector)
            && self.tile.is_multiple_of(4)
            && self.tile.is_multiple_of(self.mr * ly)
            && self.tile.is_multiple_of(self.nr * lx)
            && self.kb.is_multiple_of(4)
            && self.kb > 0
            && self.tile.is_multiple_of(self.kb)
            && (self.kb == self.tile || (self.tile == self.mr * ly && self.tile == self.nr * lx));
        if !ok {
            return Err(BakeError::Mismatch {
                stage: "transfer",
                detail: format!(
                    "invalid GEMM configuration {self:?}: the tile must be a multiple of 4, of \
                 MR × LY and of NR × LX, NR a multiple of the vector width (4, 8 or 16), and \
                 KB a multiple of 4 dividing the tile, below it only with one micro-tile per \
                 work-item"
                ),
            });
        }
        if !self.fits(info) {
            return Err(BakeError::TooLarge {
                stage: "transfer",
                detail: format!(
                "GEMM configuration {self:?} needs {} work-items and {} bytes of local memory; \
                 the device {} allows {} and {}",
                self.work_items(),
                self.local_bytes(),
                info.name,
                info.max_work_group_size,
                info.local_mem_bytes
            ),
            });
        }
        Ok(())
    }

    fn build_options(&self) -> String {
        format!(
            "-DTS={} -DMR={} -DNR={} -DVW={} -DLX={} -DLY={} -DLAYOUT={} -DKU={} -DKB={}",
            self.tile,
            self.mr,
            self.nr,
            self.vector,
            self.local[0],
            self.local[1],
            self.layout as u8,
            self.unroll,
            self.kb
        )
    }
}

impl std::fmt::Display for GemmConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "tile {t}×{t}, local {}×{}, {}×{} per work-item as float{}, A {:?} in local memory in K blocks of {}, K unrolled ×{}",
            self.local[0],
            self.local[1],
            self.mr,
            self.nr,
            self.vector,
            self.layout,
            self.kb,
            self.unroll,
            t = self.tile
        )
    }
}

/// The device's native float vector width, read from the device behind
/// the queue (the one device query [`crate::compute::DeviceInfo`] does not
/// carry).
pub(crate) fn native_float_width(gpu: &Gpu) -> u32 {
    gpu.queue()
        .device()
        .ok()
        .and_then(|id| {
            opencl3::device::Device::new(id)
                .native_vector_width_float()
                .ok()
        })
        .unwrap_or(4)
}

/// A square matrix on the device: `n × n` logical, stored row-major padded
/// with zeros to `padded × padded`, with one non-zero flag per tile.
pub struct DeviceMatrix {
    pub n: usize,
    pub padded: usize,
    data: Buffer<f32>,
    flags: Buffer<u8>,
}

/// What one product did.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct GemmRun {
    /// Device seconds (profiling events).
    pub seconds: f64,
    /// Tile products `(N / tile)³`, and how many were skipped as zero.
    pub tile_products: u64,
    pub skipped: u64,
    /// The largest `|(A·B)_ij| / |C_ij|` (0 where `C_ij = 0`); infinite when
    /// any entry of C is not finite.
    pub max_term_ratio: f64,
    /// Floating-point operations executed (skipped tiles not counted).
    pub flops: f64,
}

impl GemmRun {
    pub fn nonfinite(&self) -> bool {
        !self.max_term_ratio.is_finite()
    }
}

/// The compiled kernels for one device and configuration.
pub struct Gemm<'g> {
    gpu: &'g Gpu,
    config: GemmConfig,
    gemm: Kernel,
    flags: Kernel,
}

impl<'g> Gemm<'g> {
    /// The device's configuration for `n × n` matrices.
    pub fn device_config(gpu: &Gpu, n: usize) -> GemmConfig {
        GemmConfig::for_device(gpu.info(), native_float_width(gpu), n)
    }

    /// Builds the kernels with the device's configuration for `n × n`
    /// matrices. On a GPU: the fastest of the wide forms that build
    /// ([`GemmConfig::gpu_wide`], timed once per device and process: they
    /// give the same bits, so the choice changes no result), else the
    /// narrow forms in turn, largest first.
    pub fn new(gpu: &'g Gpu, n: usize) -> Result<Self, BakeError> {
        let config = Self::device_config(gpu, n);
        if config.layout != Layout::ATransposed {
            return Self::with_config(gpu, config);
        }
        if config.tile == 128 {
            if let Some(g) = Self::fastest_wide(gpu)? {
                return Ok(g);
            }
        }
        let mut last = None;
        for (tile, l) in [(64, 16), (32, 8), (16, 4)] {
            if tile > config.tile {
                continue;
            }
            let narrow = GemmConfig {
                tile,
                mr: 4,
                nr: 4,
                local: [l, l],
                kb: tile,
                ..config
            };
            match Self::with_config(gpu, narrow) {
                Ok(g) => return Ok(g),
                Err(e) => last = Some(e),
            }
        }
        Err(last.unwrap_or_else(|| BakeError::Mismatch {
            stage: "transfer",
            detail: format!("no GEMM configuration fits the device {}", gpu.info().name),
        }))
    }

    /// The fastest wide form on `gpu` (best device time of three 1024 ×
    /// 1024 products each), or `None` when none builds. The choice is kept
    /// per device for the process.
    fn fastest_wide(gpu: &'g Gpu) -> Result<Option<Self>, BakeError> {
        use std::sync::Mutex;
        static CHOSEN: Mutex<Vec<(usize, Option<GemmConfig>)>> = Mutex::new(Vec::new());
        let index = gpu.info().index;
        let known = CHOSEN
            .lock()
            .ok()
            .and_then(|c| c.iter().find(|(i, _)| *i == index).map(|(_, c)| *c));
        if let Some(choice) = known {
            return Ok(choice.and_then(|c| Self::with_config(gpu, c).ok()));
        }
        let built: Vec<Self> = GemmConfig::gpu_wide()
            .into_iter()
            .filter(|c| c.fits(gpu.info()))
            .filter_map(|c| Self::with_config(gpu, c).ok())
            .collect();
        let mut best: Option<(f64, Self)> = None;
        let timed = built.len() > 1;
        for g in built {
            let seconds = if timed { g.trial()? } else { 0.0 };
            if best.as_ref().is_none_or(|(t, _)| seconds < *t) {
                best = Some((seconds, g));
            }
        }
        if let Ok(mut c) = CHOSEN.lock() {
            c.push((index, best.as_ref().map(|(_, g)| g.config)));
        }
        Ok(best.map(|(_, g)| g))
    }

    /// Best device seconds of three dense 1024 × 1024 products.
    fn trial(&self) -> Result<f64, BakeError> {
        let n = 1024;
        let m: Vec<f32> = (0..n * n)
            .map(|k| ((k * 7919) % 1009) as f32 / 1009.0)
            .collect();
        let (a, _) = self.upload("GEMM trial A", n, &m)?;
        let mut c = self.alloc("GEMM trial C", n)?;
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            best = best.min(self.multiply(&a, &a, None, &mut c, false)?.seconds);
        }
        Ok(best)
    }

    /// Builds the kernels with an explicit configuration (tests use this
    /// to run the GPU form on a CPU device).
    pub fn with_config(gpu: &'g Gpu, config: GemmConfig) -> Result<Self, BakeError> {
        config.validate(gpu.info())?;
        let program = gpu.build("gemm.cl", KERNEL_SOURCE, &config.build_options())?;
        let gemm = gpu.kernel(&program, "gemm")?;
        // A kernel can allow fewer work-items than the device (registers,
        // CL_KERNEL_WORK_GROUP_SIZE).
        let allowed = gpu.local_size(&gemm, config.work_items());
        if allowed < config.work_items() {
            return Err(BakeError::TooLarge {
                stage: "transfer",
                detail: format!(
                    "GEMM configuration {config} needs {} work-items per group; the compiled \
                 kernel allows {allowed} on {}",
                    config.work_items(),
                    gpu.info().name
                ),
            });
        }
        Ok(Gemm {
            gpu,
            config,
            gemm,
            flags: gpu.kernel(&program, "tile_flags")?,
        })
    }

    pub fn config(&self) -> &GemmConfig {
        &self.config
    }

    pub fn gpu(&self) -> &Gpu {
        self.gpu
    }

    /// The padded size of an `n × n` matrix.
    pub fn padded(&self, n: usize) -> usize {
        round_up(n, self.config.tile)
    }

    /// Device bytes of one padded `n × n` matrix with its flags.
    pub fn matrix_bytes(&self, n: usize) -> u64 {
        let p = self.padded(n) as u64;
        let t = p / self.config.tile as u64;
        p * p * 4 + t * t
    }

    /// An uninitialised device matrix (a product's output).
    pub fn alloc(&self, name: &str, n: usize) -> Result<DeviceMatrix, BakeError> {
        let padded = self.padded(n);
        let tiles = padded / self.config.tile;
        Ok(DeviceMatrix {
            n,
            padded,
            data: self.gpu.buffer(name, padded * padded, Access::ReadWrite)?,
            flags: self.gpu.buffer(name, tiles * tiles, Access::ReadWrite)?,
        })
    }

    /// Uploads a row-major `n × n` matrix (padding it with zeros) and
    /// computes its tile flags. Returns the matrix and the flags kernel's
    /// device seconds.
    pub fn upload(
        &self,
        name: &str,
        n: usize,
        m: &[f32],
    ) -> Result<(DeviceMatrix, f64), BakeError> {
        assert_eq!(
            m.len(),
            n * n,
            "upload of {name}: {} values for {n} × {n}",
            m.len()
        );
        let padded = self.padded(n);
        let data = if padded == n {
            self.gpu.upload(name, m, Access::ReadWrite)?
        } else {
            let mut p = vec![0.0f32; padded * padded];
            for i in 0..n {
                p[i * padded..i * padded + n].copy_from_slice(&m[i * n..(i + 1) * n]);
            }
            self.gpu.upload(name, &p, Access::ReadWrite)?
        };
        let tiles = padded / self.config.tile;
        let flags = self.gpu.buffer(name, tiles * tiles, Access::ReadWrite)?;
        let n_u32 = padded as u32;
        let seconds = self.gpu.timed("tile_flags", || unsafe {
            ExecuteKernel::new(&self.flags)
                .set_arg(&data)
                .set_arg(&flags)
                .set_arg(&n_u32)
                .set_global_work_sizes(&[tiles, tiles])
                .set_local_work_sizes(&[1, 1])
                .enqueue_nd_range(self.gpu.queue())
        })?;
        Ok((
            DeviceMatrix {
                n,
                padded,
                data,
                flags,
            },
            seconds,
        ))
    }

    /// Reads the `n × n` matrix back (cropping the padding).
    pub fn download(&self, name: &str, m: &DeviceMatrix) -> Result<Vec<f32>, BakeError> {
        let all = self.gpu.download(name, &m.data, m.padded * m.padded)?;
        if m.padded == m.n {
            return Ok(all);
        }
        let mut out = Vec::with_capacity(m.n * m.n);
        for i in 0..m.n {
            out.extend_from_slice(&all[i * m.padded..i * m.padded + m.n]);
        }
        Ok(out)
    }

    /// The tile flags of a device matrix, row-major over tiles.
    pub fn tile_flags(&self, m: &DeviceMatrix) -> Result<Vec<u8>, BakeError> {
        let t = m.padded / self.config.tile;
        Ok(self.gpu.download("tile flags", &m.flags, t * t)?)
    }

    /// `c = d + a·b` (or `a·b` without `d`). `skip_zero_tiles` uses the
    /// operands' tile flags; off, every K block is multiplied (the same
    /// result, bit for bit; for tests and measurements). `c` must not be
    /// `a`, `b` or `d` (the borrow rules see to it).
    pub fn multiply(
        &self,
        a: &DeviceMatrix,
        b: &DeviceMatrix,
        d: Option<&DeviceMatrix>,
        c: &mut DeviceMatrix,
        skip_zero_tiles: bool,
    ) -> Result<GemmRun, BakeError> {
        let p = a.padded;
        assert!(
            b.padded == p && c.padded == p && d.is_none_or(|d| d.padded == p),
            "GEMM operands of different sizes"
        );
        let tiles = p / self.config.tile;
        let stats =
            self.gpu
                .buffer::<f32>("GEMM tile statistics", 2 * tiles * tiles, Access::WriteOnly)?;
        let (n_u32, use_d, use_flags) =
            (p as u32, u32::from(d.is_some()), u32::from(skip_zero_tiles));
        // Without D the kernel reads nothing from its `d` argument; any
        // buffer will do.
        let d_buf = d.map_or(&a.data, |d| &d.data);
        let [lx, ly] = self.config.local;
        let seconds = self.gpu.timed("gemm", || unsafe {
            ExecuteKernel::new(&self.gemm)
                .set_arg(&a.data)
                .set_arg(&b.data)
                .set_arg(d_buf)
                .set_arg(&c.data)
                .set_arg(&a.flags)
                .set_arg(&b.flags)
                .set_arg(&c.flags)
                .set_arg(&stats)
                .set_arg(&n_u32)
                .set_arg(&use_d)
                .set_arg(&use_flags)
                .set_arg(&0u64)
                .set_arg(&0u64)
                .set_arg(&0u64)
                .set_arg(&n_u32)
                .set_arg(&n_u32)
                .set_arg(&n_u32)
                .set_arg(&(tiles as u32))
                .set_arg(&1.0f32)
                .set_global_work_sizes(&[tiles * lx, tiles * ly])
                .set_local_work_sizes(&[lx, ly])
                .enqueue_nd_range(self.gpu.queue())
        })?;
        let stats = self
            .gpu
            .download("GEMM tile statistics", &stats, 2 * tiles * tiles)?;
        let mut run = GemmRun {
            seconds,
            tile_products: (tiles as u64).pow(3),
            ..GemmRun::default()
        };
        let mut executed = 0u64;
        for s in stats.chunks_exact(2) {
            // NaN cannot come out of the kernel's fmax chain, but a broken
            // driver could: treat it as non-finite too.
            let r = if s[0].is_nan() {
                f64::INFINITY
            } else {
                s[0] as f64
            };
            run.max_term_ratio = run.max_term_ratio.max(r);
            executed += s[1] as u64;
        }
        run.skipped = run.tile_products - executed;
        run.flops = 2.0 * (self.config.tile as f64).powi(3) * executed as f64;
        Ok(run)
    }
}

/// A sub-matrix operand of [`Gemm::product_at`]: a device buffer, the
/// element where the sub-matrix starts and its row pitch in elements. Its
/// size is given by the product (multiples of the tile).
#[derive(Clone, Copy)]
pub struct At<'b> {
    pub data: &'b Buffer<f32>,
    pub offset: usize,
    pub pitch: usize,
}

impl DeviceMatrix {
    /// The sub-matrix starting at (`row`, `col`) of the padded matrix.
    pub fn at(&self, row: usize, col: usize) -> At<'_> {
        At {
            data: &self.data,
            offset: row * self.padded + col,
            pitch: self.padded,
        }
    }

    /// The padded data.
    pub fn data(&self) -> &Buffer<f32> {
        &self.data
    }
}

impl Gemm<'_> {
    /// `C = αAB` or, with `accumulate`, `C += αAB` on sub-matrices:
    /// `C` is `rows × cols` tiles, `A` `rows × k` tiles, `B` `k × cols`
    /// tiles (tiles of `config.tile`). No zero-tile skipping. The operands
    /// may lie in one buffer, and `C` may overlap `A` or `B` where no
    /// work-group reads a tile that another work-group writes: a
    /// work-group reads its own output tile only in its K loop, before the
    /// epilogue writes it (the blocked LU solve's in-place panels rely on
    /// this, [`crate::solve`]).
    #[allow(clippy::too_many_arguments)]
    pub fn product_at(
        &self,
        a: At,
        b: At,
        c: At,
        rows: usize,
        cols: usize,
        k: usize,
        alpha: f32,
        accumulate: bool,
    ) -> Result<GemmRun, BakeError> {
        let ts = self.config.tile;
        assert!(
            rows > 0 && cols > 0 && k > 0,
            "empty sub-matrix product {rows} x {cols} x {k} tiles"
        );
        let groups = rows * cols;
        let stats =
            self.gpu
                .buffer::<f32>("GEMM tile statistics", 2 * groups, Access::WriteOnly)?;
        let flags_c = self
            .gpu
            .buffer::<u8>("GEMM output flags", groups, Access::WriteOnly)?;
        let use_d = if accumulate { 2u32 } else { 0 };
        let [lx, ly] = self.config.local;
        let (pa, pb, pc) = (a.pitch as u32, b.pitch as u32, c.pitch as u32);
        let seconds = self.gpu.timed("gemm (sub-matrices)", || unsafe {
            ExecuteKernel::new(&self.gemm)
                .set_arg(a.data)
                .set_arg(b.data)
                .set_arg(c.data)
                .set_arg(c.data)
                .set_arg(&flags_c)
                .set_arg(&flags_c)
                .set_arg(&flags_c)
                .set_arg(&stats)
                .set_arg(&pc)
                .set_arg(&use_d)
                .set_arg(&0u32)
                .set_arg(&(a.offset as u64))
                .set_arg(&(b.offset as u64))
                .set_arg(&(c.offset as u64))
                .set_arg(&pa)
                .set_arg(&pb)
                .set_arg(&pc)
                .set_arg(&(k as u32))
                .set_arg(&alpha)
                .set_global_work_sizes(&[cols * lx, rows * ly])
                .set_local_work_sizes(&[lx, ly])
                .enqueue_nd_range(self.gpu.queue())
        })?;
        let stats = self
            .gpu
            .download("GEMM tile statistics", &stats, 2 * groups)?;
        let nonfinite = stats.chunks_exact(2).any(|s| !(s[0] <= f32::MAX));
        Ok(GemmRun {
            seconds,
            tile_products: (groups * k) as u64,
            skipped: 0,
            max_term_ratio: if nonfinite { f64::INFINITY } else { 0.0 },
            flops: 2.0 * (ts as f64).powi(3) * (groups * k) as f64,
        })
    }

    /// Reads the `rows × cols` block at (`row`, `col`) of a device matrix
    /// (row-major, `cols` per row).
    pub fn read_block(
        &self,
        m: &DeviceMatrix,
        row: usize,
        col: usize,
        rows: usize,
        cols: usize,
    ) -> Result<Vec<f32>, BakeError> {
        assert!(row + rows <= m.padded && col + cols <= m.padded);
        let mut out = vec![0.0f32; rows * cols];
        let f = std::mem::size_of::<f32>();
        let origin = [col * f, row, 0];
        let host = [0usize, 0, 0];
        let region = [cols * f, rows, 1];
        // SAFETY: a blocking read of `rows × cols` floats, inside the
        // buffer (asserted) and inside `out`.
        unsafe {
            self.gpu
                .queue()
                .enqueue_read_buffer_rect(
                    &m.data,
                    opencl3::types::CL_BLOCKING,
                    origin.as_ptr(),
                    host.as_ptr(),
                    region.as_ptr(),
                    m.padded * f,
                    0,
                    cols * f,
                    0,
                    out.as_mut_ptr().cast(),
                    &[],
                )
                .map_err(|e| radiosity_core::error::ClError::Api {
                    what: "reading a block of a matrix".into(),
                    code: e.to_string(),
                })?;
        }
        Ok(out)
    }
}

/// CPU reference of the `tile_flags` kernel: one flag per `tile × tile`
/// tile of the `n × n` matrix padded with zeros to a multiple of `tile`.
pub fn tile_flags_cpu(m: &[f32], n: usize, tile: usize) -> Vec<u8> {
    let t = n.div_ceil(tile);
    let mut flags = vec![0u8; t * t];
    for i in 0..n {
        for j in 0..n {
            if m[i * n + j] != 0.0 {
                flags[(i / tile) * t + j / tile] = 1;
            }
        }
    }
    flags
}

/// A row-major f32 matrix as a faer matrix.
pub fn to_faer<T: Copy, U>(m: &[T], n: usize, f: impl Fn(T) -> U) -> faer::Mat<U> {
    faer::Mat::from_fn(n, n, |i, j| f(m[i * n + j]))
}

/// CPU reference of the kernel: `d + a·b` (or `a·b`) in f64 with faer.
pub fn reference_product(a: &[f32], b: &[f32], d: Option<&[f32]>, n: usize) -> Vec<f64> {
    let (fa, fb) = (to_faer(a, n, f64::from), to_faer(b, n, f64::from));
    let mut c = match d {
        Some(d) => to_faer(d, n, f64::from),
        None => faer::Mat::zeros(n, n),
    };
    faer::linalg::matmul::matmul(
        c.as_mut(),
        faer::Accum::Add,
        fa.as_ref(),
        fb.as_ref(),
        1.0,
        faer::Par::rayon(0),
    );
    (0..n * n).map(|e| c[(e / n, e % n)]).collect()
}

/// Relative Frobenius error `‖x − r‖_F / ‖r‖_F` (0 when both are zero).
pub fn relative_frobenius(x: &[f32], r: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (&x, &r) in x.iter().zip(r) {
        num += (x as f64 - r).powi(2);
        den += r * r;
    }
    if den == 0.0 {
        num.sqrt()
    } else {
        (num / den).sqrt()
    }
}
