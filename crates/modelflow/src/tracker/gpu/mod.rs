//! The GPU path (`--device gpu`): the solver's per-pixel work — warp, Catmull–Rom sample with
//! its exact derivatives, the per-(triangle, camera) gain fit, the robust loss and the normal
//! equations' 3×3 vertex-pair blocks — on an NVIDIA GPU. Everything else (templates, the
//! regularisers, the linear solve, the step control) stays on the CPU: the solver sees the
//! GPU only through [`Problem::evaluate`](crate::tracker::solve), which gets the same
//! per-triangle sums from it as from its own loop.
//!
//! CUDA through `cudarc`, which loads `libcuda.so` and `libnvrtc.so` at run time: the same
//! binary builds and runs without the CUDA toolkit or a GPU (CI), and [`Gpu::open`] says why
//! when there is none. The kernels (`kernel.cu`, CUDA C written by hand: it is the product's
//! inner loop) are compiled by NVRTC when a [`Gpu`] is opened, with floating-point
//! contraction off so that each pixel's arithmetic is the CPU's operation for operation; only
//! the order in which a patch's pixels are summed differs (a fixed tree, no atomics), so runs
//! repeat to the bit and agree with the CPU to rounding (docs/gpu.md).
//!
//! Invariant: no I/O, no printing; a failure on the device becomes [`Error::Gpu`].

use crate::error::{Error, Result};
use crate::tracker::solve::{GainModel, Interpolation, Loss, Problem, SolverOptions, TriAccum};
use nalgebra::{Matrix3, Point3, Vector3};
use std::sync::{Arc, Mutex};

mod cg;

/// The kernels' source: the evaluation's, then the linear solve's.
const KERNEL: &str = concat!(include_str!("kernel.cu"), include_str!("pcg.cu"));

/// Doubles per patch record and per triangle's blocks (see `kernel.cu`).
const REC: usize = 67;
const BLOCKS: usize = REC - 4;
/// Patches per thread block (one warp each).
const PATCHES_PER_BLOCK: u32 = 4;

const FLAG_TUKEY: i32 = 1;
const FLAG_CUBIC: i32 = 2;
const FLAG_SYSTEM: i32 = 4;
const FLAG_HIST: i32 = 8;
const FLAG_MOVING: i32 = 16;
const FLAG_LAG: i32 = 32;
const GAIN_SHIFT: i32 = 8;

/// An open GPU: its context, stream and compiled kernels. Open one per run and hand it to the
/// tracker ([`Tracker::set_gpu`](crate::tracker::Tracker::set_gpu)).
pub struct Gpu {
    backend: Backend,
    name: String,
    stats: Mutex<GpuStats>,
    /// Systems of this many rows or more are solved on the GPU ([`Gpu::solves`]).
    solve_from: usize,
}

/// Rows from which the linear solve runs on the GPU by default: below it a solve's dozens of
/// small launches and read-backs cost more than the CPU's product (`MODELFLOW_GPU_SOLVE_FROM`
/// sets another, for measuring; docs/gpu.md).
const SOLVE_FROM: usize = 4096;

/// Where the GPU path's time went since the [`Gpu`] was opened (wall time, seconds): what a
/// benchmark reports to say whether the device, the bus or the host is the bottleneck.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct GpuStats {
    /// Problems uploaded (one per frame and pyramid level).
    pub uploads: u64,
    /// Preparing (flattening) the uploads on the host.
    pub upload_host_seconds: f64,
    /// Copying them to the device.
    pub upload_copy_seconds: f64,
    /// Evaluations run.
    pub evaluations: u64,
    /// The kernels, launch to completion.
    pub kernel_seconds: f64,
    /// Copying the positions up and the sums back.
    pub transfer_seconds: f64,
    /// Linear solves run on the GPU (from `MODELFLOW_GPU_SOLVE_FROM` rows, 4 096 by default).
    pub linear_solves: u64,
    /// Their conjugate-gradient iterations.
    pub cg_iterations: u64,
    /// Their wall time, uploads and the preconditioner's set-up on the CPU included.
    pub linear_solve_seconds: f64,
    /// Of it, the set-up: the preconditioner built on the CPU and the system uploaded.
    pub linear_setup_seconds: f64,
}

impl GpuStats {
    /// What happened between `earlier` and `self`.
    pub fn since(&self, earlier: &GpuStats) -> GpuStats {
        GpuStats {
            uploads: self.uploads - earlier.uploads,
            upload_host_seconds: self.upload_host_seconds - earlier.upload_host_seconds,
            upload_copy_seconds: self.upload_copy_seconds - earlier.upload_copy_seconds,
            evaluations: self.evaluations - earlier.evaluations,
            kernel_seconds: self.kernel_seconds - earlier.kernel_seconds,
            transfer_seconds: self.transfer_seconds - earlier.transfer_seconds,
            linear_solves: self.linear_solves - earlier.linear_solves,
            cg_iterations: self.cg_iterations - earlier.cg_iterations,
            linear_solve_seconds: self.linear_solve_seconds - earlier.linear_solve_seconds,
            linear_setup_seconds: self.linear_setup_seconds - earlier.linear_setup_seconds,
        }
    }
}

impl std::fmt::Debug for Gpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gpu").field("name", &self.name).finish()
    }
}

enum Backend {
    Cuda(cuda::Cuda),
    /// The kernels compiled as C and run on the CPU, one patch at a time (tests only): the
    /// host side and the kernels' arithmetic checked without a GPU.
    #[cfg(test)]
    Emulated,
}

impl Gpu {
    /// Opens the first CUDA device and compiles the kernels. Fails with a message that says
    /// what is missing: the driver library, the NVRTC library, a device, or the compile.
    pub fn open() -> Result<Gpu> {
        let (backend, name) = cuda::Cuda::open()?;
        let solve_from = std::env::var("MODELFLOW_GPU_SOLVE_FROM")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(SOLVE_FROM);
        Ok(Gpu {
            backend: Backend::Cuda(backend),
            name,
            stats: Mutex::new(GpuStats::default()),
            solve_from,
        })
    }

    /// The device's name, as the driver gives it (e.g. `NVIDIA H100 80GB HBM3`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Where the time went since the GPU was opened.
    pub fn stats(&self) -> GpuStats {
        self.stats.lock().map(|s| *s).unwrap_or_default()
    }

    fn record(&self, f: impl FnOnce(&mut GpuStats)) {
        if let Ok(mut s) = self.stats.lock() {
            f(&mut s);
        }
    }

    /// The kernels emulated on the CPU, every linear solve on the "GPU" whatever its size.
    #[cfg(test)]
    pub(crate) fn emulated() -> Gpu {
        Gpu {
            backend: Backend::Emulated,
            name: "emulated on the CPU".into(),
            stats: Mutex::new(GpuStats::default()),
            solve_from: 0,
        }
    }

    /// Uploads what a problem's evaluations share (its patches and pixels, the next frame's
    /// images, the cameras).
    pub(crate) fn upload(self: &Arc<Self>, p: &Problem<'_>) -> Result<Uploaded> {
        let t0 = std::time::Instant::now();
        let ncam = p.projections.len();
        let tris: Vec<u32> = p.triangles.iter().flatten().copied().collect();
        let mut patches = Vec::with_capacity(p.patches.len() * 4);
        let mut weights = Vec::with_capacity(p.patches.len());
        for q in p.patches {
            patches.extend_from_slice(&[
                q.triangle,
                u32::from(q.camera) | (u32::from(q.source) << 16),
                q.start,
                q.end,
            ]);
            weights.push(q.weight);
        }
        let mut img_off = Vec::with_capacity(ncam);
        let mut img_size = Vec::with_capacity(2 * ncam);
        let mut total = 0u64;
        for img in &p.targets {
            img_off.push(total);
            img_size.extend_from_slice(&[img.width() as i32, img.height() as i32]);
            total += (img.width() * img.height()) as u64;
        }
        let proj: Vec<f64> = p
            .projections
            .iter()
            .flat_map(|q| {
                let m = q.matrix();
                (0..3)
                    .flat_map(move |r| (0..4).map(move |c| m[(r, c)]))
                    .collect::<Vec<_>>()
            })
            .collect();
        let flat =
            |x: &[Point3<f64>]| -> Vec<f64> { x.iter().flat_map(|v| [v.x, v.y, v.z]).collect() };
        let (lag, prev, gap) = match &p.lag {
            Some(l) => {
                let mut off = l.per_camera().ok_or_else(|| {
                    Error::Gpu(
                        "a rolling shutter's per-vertex lag is solved on the CPU only".into(),
                    )
                })?;
                off.resize(ncam, 0.0);
                (off, flat(l.previous), l.gap)
            }
            None => (vec![0.0; ncam], Vec::new(), 1.0),
        };
        let x0 = p.moving_source.map(flat).unwrap_or_default();
        let mut ranges = Vec::with_capacity(p.by_triangle.len() * 2);
        for (_, r) in p.by_triangle {
            ranges.extend_from_slice(&[r.start as u32, r.end as u32]);
        }
        let host = HostInputs {
            tris,
            patches,
            weights,
            img_off,
            img_size,
            proj,
            lag,
            prev,
            gap,
            x0,
            ranges,
            edges: crate::tracker::solve::histogram_edges().to_vec(),
            npatches: p.patches.len(),
            ntri: p.by_triangle.len(),
            has_lag: p.lag.is_some(),
            moving: p.moving_source.is_some(),
        };
        let t1 = std::time::Instant::now();
        // The template pixels and the images go up straight from the problem's memory.
        let device = match &self.backend {
            Backend::Cuda(c) => Device::Cuda(Box::new(c.upload(&host, p)?)),
            #[cfg(test)]
            Backend::Emulated => Device::Emulated {
                pixels: pixel_floats(p.pixels).to_vec(),
                images: p
                    .targets
                    .iter()
                    .flat_map(|i| crate::base::image::RgbImage::pixels(i).as_flattened())
                    .copied()
                    .collect(),
            },
        };
        let (host_s, copy_s) = ((t1 - t0).as_secs_f64(), t1.elapsed().as_secs_f64());
        self.record(|s| {
            s.uploads += 1;
            s.upload_host_seconds += host_s;
            s.upload_copy_seconds += copy_s;
        });
        Ok(Uploaded {
            gpu: Arc::clone(self),
            host,
            device: Mutex::new(device),
            failure: Mutex::new(None),
        })
    }
}

/// What a problem's evaluations read, flattened for the kernels (see `kernel.cu`).
pub(crate) struct HostInputs {
    tris: Vec<u32>,
    patches: Vec<u32>,
    weights: Vec<f32>,
    img_off: Vec<u64>,
    img_size: Vec<i32>,
    proj: Vec<f64>,
    lag: Vec<f64>,
    prev: Vec<f64>,
    gap: f64,
    x0: Vec<f64>,
    ranges: Vec<u32>,
    edges: Vec<f64>,
    npatches: usize,
    ntri: usize,
    has_lag: bool,
    moving: bool,
}

enum Device {
    Cuda(Box<cuda::Buffers>),
    /// The pixels and images the emulated kernels read (on the GPU, in `Buffers`).
    #[cfg(test)]
    Emulated {
        pixels: Vec<f32>,
        images: Vec<f32>,
    },
}

/// The template pixels as the kernels read them: six `f32` each (`PixelSample` is `repr(C)`).
fn pixel_floats(p: &[crate::tracker::patch::PixelSample]) -> &[f32] {
    const _: () = assert!(std::mem::size_of::<crate::tracker::patch::PixelSample>() == 24);
    // SAFETY: `PixelSample` is `repr(C)` of two `[f32; 3]`: 24 bytes, `f32`-aligned, no
    // padding (asserted above), so the slice is `6·len` initialised `f32`s.
    unsafe { std::slice::from_raw_parts(p.as_ptr().cast::<f32>(), p.len() * 6) }
}

/// One problem's inputs on the device; [`Uploaded::evaluate`] runs the kernels on them.
pub(crate) struct Uploaded {
    gpu: Arc<Gpu>,
    host: HostInputs,
    device: Mutex<Device>,
    /// The first failure on the device, if any: the solve goes on on the CPU, and the tracker
    /// reports it after the frame ([`Uploaded::failure`]).
    failure: Mutex<Option<Error>>,
}

/// The per-triangle sums of one evaluation, as the kernels return them.
pub(crate) struct Sums {
    /// Per `by_triangle` entry: cost, pixels, weight, rejected.
    scalars: Vec<f64>,
    /// Per entry, when the normal equations were asked for: six 3×3 blocks and three vectors.
    blocks: Vec<f64>,
    /// The residual histogram's bins, when asked for.
    pub hist: Option<Vec<u64>>,
}

impl Uploaded {
    /// The photometric sums at `x`, or `None` after a failure on the device (kept for
    /// [`Uploaded::failure`]), when the caller evaluates on the CPU instead.
    pub(crate) fn evaluate(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
        system: bool,
        hist: bool,
    ) -> Option<Vec<TriAccum>> {
        self.evaluate_sums(x, opts, system, hist)
            .map(|s| self.accums(&s, system))
    }

    /// The residual histogram's bins at `x` (for the weighted median), `None` after a failure.
    pub(crate) fn histogram(&self, x: &[Point3<f64>], opts: &SolverOptions) -> Option<Vec<u64>> {
        self.evaluate_sums(x, opts, false, true)
            .and_then(|s| s.hist)
    }

    /// [`Uploaded::evaluate`] and the histogram from the same pass.
    pub(crate) fn evaluate_with_histogram(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
        system: bool,
    ) -> Option<(Vec<TriAccum>, Vec<u64>)> {
        let s = self.evaluate_sums(x, opts, system, true)?;
        let acc = self.accums(&s, system);
        Some((acc, s.hist.unwrap_or_default()))
    }

    /// `sparse::solve_pcg_until` on the GPU for a system large enough to be worth it there
    /// ([`Gpu::solves`]); `None` below that or after a failure on the device (kept for
    /// [`Uploaded::failure`]), when the caller solves on the CPU.
    pub(crate) fn solve_pcg(
        &self,
        a: &crate::tracker::sparse::BlockSparse,
        b: &[Vector3<f64>],
        stop: crate::tracker::sparse::CgStop,
    ) -> Option<(Vec<Vector3<f64>>, crate::tracker::sparse::CgSummary)> {
        if !self.gpu.solves(a.dim()) || self.failure.lock().map(|f| f.is_some()).unwrap_or(true) {
            return None;
        }
        match self.gpu.solve_pcg(a, b, stop) {
            Ok(r) => Some(r),
            Err(e) => {
                if let Ok(mut f) = self.failure.lock() {
                    f.get_or_insert(e);
                }
                None
            }
        }
    }

    /// The first failure on the device since the upload, taken (so it is reported once).
    pub(crate) fn failure(&self) -> Option<Error> {
        self.failure.lock().ok().and_then(|mut f| f.take())
    }

    fn evaluate_sums(
        &self,
        x: &[Point3<f64>],
        opts: &SolverOptions,
        system: bool,
        hist: bool,
    ) -> Option<Sums> {
        if self.failure.lock().map(|f| f.is_some()).unwrap_or(true) {
            return None;
        }
        let h = &self.host;
        let xs: Vec<f64> = x.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        let mut flags = 0;
        if opts.loss == Loss::Tukey {
            flags |= FLAG_TUKEY;
        }
        if opts.interpolation == Interpolation::Cubic {
            flags |= FLAG_CUBIC;
        }
        if system {
            flags |= FLAG_SYSTEM;
        }
        if hist {
            flags |= FLAG_HIST;
        }
        if h.moving {
            flags |= FLAG_MOVING;
        }
        if h.has_lag {
            flags |= FLAG_LAG;
        }
        let gain = match opts.gain {
            GainModel::Off => 0,
            GainModel::Constant => 1,
            GainModel::Linear => 2,
        };
        flags |= gain << GAIN_SHIFT;
        let scalars = KernelScalars {
            huber: opts.huber,
            tukey_px: opts.tukey_px,
            patch_scale: opts.patch_scale,
            gain_range: opts.gain_range,
            flags,
            system,
        };
        let result = match (&self.gpu.backend, &mut *self.device.lock().ok()?) {
            (Backend::Cuda(c), Device::Cuda(b)) => {
                c.evaluate(b, h, &xs, &scalars).map(|(s, k, t)| {
                    self.gpu.record(|st| {
                        st.evaluations += 1;
                        st.kernel_seconds += k;
                        st.transfer_seconds += t;
                    });
                    s
                })
            }
            #[cfg(test)]
            (Backend::Emulated, Device::Emulated { pixels, images }) => {
                Ok(emulated::evaluate(h, pixels, images, &xs, &scalars))
            }
            #[cfg(test)]
            _ => unreachable!("a problem uploaded to one backend evaluated on another"),
        };
        match result {
            Ok(s) => Some(s),
            Err(e) => {
                if let Ok(mut f) = self.failure.lock() {
                    f.get_or_insert(e);
                }
                None
            }
        }
    }

    fn accums(&self, s: &Sums, system: bool) -> Vec<TriAccum> {
        (0..self.host.ntri)
            .map(|t| {
                let c = &s.scalars[4 * t..4 * t + 4];
                let mut acc = TriAccum {
                    cost: c[0],
                    pixels: c[1] as u32,
                    weight: c[2],
                    rejected: c[3] as u32,
                    h: [Matrix3::zeros(); 6],
                    g: [Vector3::zeros(); 3],
                };
                if system {
                    let b = &s.blocks[BLOCKS * t..BLOCKS * (t + 1)];
                    for k in 0..6 {
                        acc.h[k] = Matrix3::from_row_slice(&b[9 * k..9 * k + 9]);
                    }
                    for i in 0..3 {
                        acc.g[i] = Vector3::from_row_slice(&b[54 + 3 * i..54 + 3 * i + 3]);
                    }
                }
                acc
            })
            .collect()
    }
}

/// The per-evaluation scalars the kernel takes.
struct KernelScalars {
    huber: f64,
    tukey_px: f64,
    patch_scale: f64,
    gain_range: f64,
    flags: i32,
    system: bool,
}

/// The CUDA backend (cudarc, driver and NVRTC loaded at run time).
mod cuda {
    use super::{HostInputs, KernelScalars, Sums, BLOCKS, KERNEL, PATCHES_PER_BLOCK, REC};
    use crate::base::image::RgbImage;
    use crate::error::{Error, Result};
    use crate::tracker::solve::Problem;
    use cudarc::driver::{
        CudaContext, CudaFunction, CudaSlice, CudaStream, DeviceRepr, LaunchConfig, PushKernelArg,
        ValidAsZeroBits,
    };
    use std::sync::Arc;

    pub(super) struct Cuda {
        pub(super) stream: Arc<CudaStream>,
        evaluate: CudaFunction,
        sum: CudaFunction,
        pub(super) cg: super::cg::cuda::CgKernels,
    }

    pub(super) struct Buffers {
        tris: CudaSlice<u32>,
        patches: CudaSlice<u32>,
        weights: CudaSlice<f32>,
        pixels: CudaSlice<f32>,
        images: CudaSlice<f32>,
        img_off: CudaSlice<u64>,
        img_size: CudaSlice<i32>,
        proj: CudaSlice<f64>,
        lag: CudaSlice<f64>,
        prev: CudaSlice<f64>,
        x0: CudaSlice<f64>,
        ranges: CudaSlice<u32>,
        edges: CudaSlice<f64>,
        x: CudaSlice<f64>,
        recs: CudaSlice<f64>,
        scalars: CudaSlice<f64>,
        blocks: CudaSlice<f64>,
        hist: CudaSlice<u64>,
    }

    fn gpu_err(what: &str) -> impl Fn(cudarc::driver::DriverError) -> Error + '_ {
        move |e| Error::Gpu(format!("{what}: {e}"))
    }

    /// The macros that make `kernel.cu` CUDA (`emulate.c` makes it C).
    pub(super) const PRELUDE: &str = "#define DEV static __device__ __forceinline__\n\
        #define KERNEL extern \"C\" __global__\n\
        #define LDG(p) __ldg(p)\n\
        #define BLOCK_X blockIdx.x\n\
        #define THREAD_X threadIdx.x\n\
        #define THREAD_Y threadIdx.y\n\
        #define BLOCK_DIM_X blockDim.x\n\
        #define SHARED __shared__\n\
        #define SYNCWARP() __syncwarp()\n\
        #define LAUNCH_BOUNDS __launch_bounds__(128, 4)\n";

    /// The kernels compiled by NVRTC for compute capability `major.minor` (needs the NVRTC
    /// library, not a device).
    pub(super) fn compile(major: i32, minor: i32) -> Result<cudarc::nvrtc::Ptx> {
        // SAFETY: only tries to load the library.
        if !unsafe { cudarc::nvrtc::sys::is_culib_present() } {
            return Err(Error::Gpu(
                "NVRTC (libnvrtc.so, CUDA's runtime compiler, part of the CUDA toolkit or the \
                 nvidia-cuda-nvrtc package) could not be loaded; put its folder on \
                 LD_LIBRARY_PATH"
                    .into(),
            ));
        }
        let arch: &'static str = Box::leak(format!("compute_{major}{minor}").into_boxed_str());
        cudarc::nvrtc::compile_ptx_with_opts(
            format!("{PRELUDE}{KERNEL}"),
            cudarc::nvrtc::CompileOptions {
                // Each pixel's arithmetic as the CPU does it (no fused multiply-add).
                fmad: Some(false),
                arch: Some(arch),
                name: Some("modelflow.cu".into()),
                ..Default::default()
            },
        )
        .map_err(|e| Error::Gpu(format!("compiling the kernels with NVRTC: {e}")))
    }

    impl Cuda {
        pub(super) fn open() -> Result<(Cuda, String)> {
            // cudarc panics when a library is missing: ask first, so the answer is an error.
            // SAFETY: only tries to load the libraries.
            if !unsafe { cudarc::driver::sys::is_culib_present() } {
                return Err(Error::Gpu(
                    "no CUDA driver found (libcuda.so could not be loaded); install NVIDIA's \
                     driver, or run with --device cpu"
                        .into(),
                ));
            }
            let n = CudaContext::device_count().map_err(gpu_err("counting CUDA devices"))?;
            if n < 1 {
                return Err(Error::Gpu("the CUDA driver sees no device".into()));
            }
            let ctx = CudaContext::new(0).map_err(gpu_err("opening CUDA device 0"))?;
            // SAFETY: every buffer is used on the one stream below only, so the per-use
            // events cudarc records for cross-stream safety (two per buffer and launch) are
            // not needed.
            unsafe { ctx.disable_event_tracking() };
            let name = ctx.name().map_err(gpu_err("reading the device's name"))?;
            let (major, minor) = ctx
                .compute_capability()
                .map_err(gpu_err("reading the device's compute capability"))?;
            let ptx = compile(major, minor)?;
            let module = ctx
                .load_module(ptx)
                .map_err(gpu_err("loading the kernels"))?;
            // Which register budget the per-patch kernel runs with: held to 128 (the default,
            // twice the occupancy) or as compiled (`MODELFLOW_GPU_KERNEL=unbounded`, kept for
            // measuring the choice again on other GPUs; docs/gpu.md).
            let kernel = match std::env::var("MODELFLOW_GPU_KERNEL").as_deref() {
                Ok("unbounded") => "evaluate_patches",
                _ => "evaluate_patches_bounded",
            };
            let evaluate = module
                .load_function(kernel)
                .map_err(gpu_err("loading the per-patch kernel"))?;
            let sum = module
                .load_function("sum_triangles")
                .map_err(gpu_err("loading sum_triangles"))?;
            let cg = super::cg::cuda::CgKernels::load(&module)?;
            let stream = ctx.default_stream();
            Ok((
                Cuda {
                    stream,
                    evaluate,
                    sum,
                    cg,
                },
                name,
            ))
        }

        pub(super) fn up<T: DeviceRepr>(&self, v: &[T], what: &str) -> Result<CudaSlice<T>> {
            if v.is_empty() {
                // A zero-length allocation is refused by some drivers: one element instead.
                // SAFETY: never read (the kernel reads it only when its flag says it holds data).
                return unsafe { self.stream.alloc::<T>(1) }.map_err(gpu_err(what));
            }
            self.stream.clone_htod(v).map_err(gpu_err(what))
        }

        pub(super) fn zeros<T: DeviceRepr + ValidAsZeroBits>(
            &self,
            n: usize,
            what: &str,
        ) -> Result<CudaSlice<T>> {
            self.stream
                .alloc_zeros::<T>(n.max(1))
                .map_err(gpu_err(what))
        }

        pub(super) fn upload(&self, h: &HostInputs, p: &Problem<'_>) -> Result<Buffers> {
            let total: usize = p.targets.iter().map(|i| i.width() * i.height() * 3).sum();
            let mut images = self.zeros::<f32>(total, "allocating the next frame's images")?;
            for (img, &off) in p.targets.iter().zip(&h.img_off) {
                let src = RgbImage::pixels(img).as_flattened();
                let start = 3 * off as usize;
                let mut view = images.slice_mut(start..start + src.len());
                self.stream
                    .memcpy_htod(src, &mut view)
                    .map_err(gpu_err("uploading the next frame's images"))?;
            }
            Ok(Buffers {
                tris: self.up(&h.tris, "uploading the triangles")?,
                patches: self.up(&h.patches, "uploading the patches")?,
                weights: self.up(&h.weights, "uploading the patches' weights")?,
                pixels: self.up(
                    super::pixel_floats(p.pixels),
                    "uploading the template pixels",
                )?,
                images,
                img_off: self.up(&h.img_off, "uploading the images' offsets")?,
                img_size: self.up(&h.img_size, "uploading the images' sizes")?,
                proj: self.up(&h.proj, "uploading the cameras")?,
                lag: self.up(&h.lag, "uploading the cameras' time offsets")?,
                prev: self.up(&h.prev, "uploading the previous positions")?,
                x0: self.up(&h.x0, "uploading the source positions")?,
                ranges: self.up(&h.ranges, "uploading the triangles' patch ranges")?,
                edges: self.up(&h.edges, "uploading the histogram's edges")?,
                x: self.zeros(3, "allocating the positions")?,
                recs: self.zeros(REC * h.npatches, "allocating the patch records")?,
                scalars: self.zeros(4 * h.ntri, "allocating the triangle sums")?,
                blocks: self.zeros(BLOCKS * h.ntri, "allocating the triangle blocks")?,
                hist: self.zeros(
                    super::super::solve::HISTOGRAM_BINS,
                    "allocating the histogram",
                )?,
            })
        }

        pub(super) fn evaluate(
            &self,
            b: &mut Buffers,
            h: &HostInputs,
            xs: &[f64],
            k: &KernelScalars,
        ) -> Result<(Sums, f64, f64)> {
            let t0 = std::time::Instant::now();
            if b.x.len() < xs.len() {
                b.x = self.zeros(xs.len(), "allocating the positions")?;
            }
            self.stream
                .memcpy_htod(xs, &mut b.x)
                .map_err(gpu_err("uploading the positions"))?;
            let want_hist = k.flags & super::FLAG_HIST != 0;
            if want_hist {
                self.stream
                    .memset_zeros(&mut b.hist)
                    .map_err(gpu_err("clearing the histogram"))?;
            }
            self.stream
                .synchronize()
                .map_err(gpu_err("uploading the positions"))?;
            let t1 = std::time::Instant::now();
            let npatches = h.npatches as i32;
            let ntri = h.ntri as i32;
            if h.npatches > 0 {
                let blocks = (h.npatches as u32).div_ceil(PATCHES_PER_BLOCK);
                let cfg = LaunchConfig {
                    grid_dim: (blocks, 1, 1),
                    block_dim: (32, PATCHES_PER_BLOCK, 1),
                    shared_mem_bytes: 0,
                };
                let mut l = self.stream.launch_builder(&self.evaluate);
                l.arg(&b.x)
                    .arg(&b.x0)
                    .arg(&b.prev)
                    .arg(&b.proj)
                    .arg(&b.lag)
                    .arg(&h.gap)
                    .arg(&b.tris)
                    .arg(&b.patches)
                    .arg(&b.weights)
                    .arg(&b.pixels)
                    .arg(&b.images)
                    .arg(&b.img_off)
                    .arg(&b.img_size)
                    .arg(&npatches)
                    .arg(&k.huber)
                    .arg(&k.tukey_px)
                    .arg(&k.patch_scale)
                    .arg(&k.gain_range)
                    .arg(&k.flags)
                    .arg(&b.edges)
                    .arg(&mut b.recs)
                    .arg(&mut b.hist);
                // SAFETY: the arguments match `evaluate_patches`' signature, and every buffer
                // holds what the kernel reads (sizes set at upload from the same inputs).
                unsafe { l.launch(cfg) }.map_err(gpu_err("running evaluate_patches"))?;
            }
            if h.ntri > 0 {
                let system = i32::from(k.system);
                let cfg = LaunchConfig::for_num_elems(h.ntri as u32);
                let mut l = self.stream.launch_builder(&self.sum);
                l.arg(&b.recs)
                    .arg(&b.ranges)
                    .arg(&ntri)
                    .arg(&system)
                    .arg(&mut b.scalars)
                    .arg(&mut b.blocks);
                // SAFETY: as above, for `sum_triangles`.
                unsafe { l.launch(cfg) }.map_err(gpu_err("running sum_triangles"))?;
            }
            self.stream
                .synchronize()
                .map_err(gpu_err("running the kernels"))?;
            let t2 = std::time::Instant::now();
            let scalars = self
                .stream
                .clone_dtoh(&b.scalars)
                .map_err(gpu_err("reading the triangle sums"))?;
            let blocks = if k.system {
                self.stream
                    .clone_dtoh(&b.blocks)
                    .map_err(gpu_err("reading the triangle blocks"))?
            } else {
                Vec::new()
            };
            let hist = if want_hist {
                Some(
                    self.stream
                        .clone_dtoh(&b.hist)
                        .map_err(gpu_err("reading the histogram"))?,
                )
            } else {
                None
            };
            let kernel = (t2 - t1).as_secs_f64();
            let transfer = (t1 - t0).as_secs_f64() + t2.elapsed().as_secs_f64();
            Ok((
                Sums {
                    scalars,
                    blocks,
                    hist,
                },
                kernel,
                transfer,
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    /// Wherever NVRTC is installed (no GPU needed), the kernels compile for the GPUs the path
    /// targets (Turing to Hopper); elsewhere (CI) the test is skipped and says why.
    #[test]
    fn the_kernels_compile_with_nvrtc() {
        for (major, minor) in [(7, 5), (8, 0), (9, 0)] {
            match super::cuda::compile(major, minor) {
                Ok(ptx) => {
                    let src = ptx.to_src();
                    for k in [
                        "evaluate_patches",
                        "sum_triangles",
                        "cg_mul",
                        "cg_precondition",
                    ] {
                        assert!(src.contains(k), "compute_{major}{minor}: no {k} in the PTX");
                    }
                }
                Err(e) if e.to_string().contains("could not be loaded") => {
                    eprintln!("SKIPPED (no NVRTC here): {e}");
                    return;
                }
                Err(e) => panic!("compute_{major}{minor}: {e}"),
            }
        }
    }

    /// What NVRTC provides without headers and clang's CUDA mode (run without the CUDA
    /// toolkit, `-nocudainc`) does not: the attributes' keywords and the device functions the
    /// kernels call, declared only (the PTX leaves them unresolved, which `-S` allows).
    const CLANG_DECLARATIONS: &str = r#"
#include "__clang_cuda_builtin_vars.h"
#define __device__ __attribute__((device))
#define __global__ __attribute__((global))
#define __shared__ __attribute__((shared))
#define __forceinline__ __inline__ __attribute__((always_inline))
#define __launch_bounds__(...) __attribute__((launch_bounds(__VA_ARGS__)))
__device__ unsigned long long atomicAdd(unsigned long long*, unsigned long long);
__device__ void __syncwarp(unsigned mask = 0xffffffffu);
template <class T> __device__ T __ldg(const T* p);
__device__ bool isfinite(double);
__device__ bool isfinite(float);
extern "C" {
__device__ double sqrt(double); __device__ float sqrtf(float);
__device__ double fabs(double); __device__ float fabsf(float);
__device__ double fmin(double, double); __device__ double fmax(double, double);
__device__ double floor(double); __device__ float floorf(float);
__device__ double round(double); __device__ double log1p(double);
__device__ double exp(double); __device__ double log(double);
}
"#;

    /// Where clang is installed (no CUDA toolkit, no GPU needed), the kernels as the GPU path
    /// compiles them (`cuda::PRELUDE` + the sources) compile to PTX in clang's CUDA mode with
    /// every warning on and none given: the CUDA-only half of the sources (the macros `emulate.c`
    /// maps to C) is checked on machines that have neither NVRTC nor a GPU. Elsewhere (CI) the
    /// test is skipped and says why. NVRTC is the compiler the path uses; this is a second
    /// front end's reading of the same text.
    #[test]
    fn the_kernels_compile_to_ptx_with_clang_where_clang_is_installed() {
        let found = [
            "clang", "clang-19", "clang-18", "clang-17", "clang-16", "clang-15", "clang-14",
        ]
        .into_iter()
        .find(|c| {
            std::process::Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        });
        let Some(clang) = found else {
            eprintln!("SKIPPED (no clang here): the kernels' CUDA text is not compiled");
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        let (src, decl, ptx) = (
            dir.path().join("modelflow.cu"),
            dir.path().join("declarations.h"),
            dir.path().join("modelflow.ptx"),
        );
        std::fs::write(&src, format!("{}{}", super::cuda::PRELUDE, super::KERNEL)).unwrap();
        std::fs::write(&decl, CLANG_DECLARATIONS).unwrap();
        let out = std::process::Command::new(clang)
            .args(["-x", "cuda", "--cuda-device-only", "--cuda-gpu-arch=sm_80"])
            .args(["-nocudainc", "-nocudalib", "-O2", "-S", "-Wall", "-Wextra"])
            .args(["-Wno-unused-parameter", "-Wno-unused-function"])
            .arg("-include")
            .arg(&decl)
            .arg(&src)
            .arg("-o")
            .arg(&ptx)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{clang} failed:\n{stderr}");
        assert!(stderr.trim().is_empty(), "{clang} warned:\n{stderr}");
        let text = std::fs::read_to_string(&ptx).unwrap();
        for k in [
            "evaluate_patches",
            "sum_triangles",
            "cg_mul",
            "cg_precondition",
        ] {
            assert!(
                text.contains(&format!(".entry {k}(")),
                "no kernel {k} in clang's PTX"
            );
        }
    }
}

/// The kernels compiled as C (`emulate.c`, one lane per warp), for the tests.
#[cfg(test)]
mod emulated {
    use super::{HostInputs, KernelScalars, Sums, BLOCKS, REC};

    unsafe extern "C" {
        fn modelflow_emu_evaluate_patches(
            x: *const f64,
            x0: *const f64,
            prev: *const f64,
            proj: *const f64,
            lag: *const f64,
            gap: f64,
            tris: *const u32,
            patches: *const u32,
            weights: *const f32,
            pixels: *const f32,
            images: *const f32,
            img_off: *const u64,
            img_size: *const i32,
            npatches: i32,
            huber: f64,
            tukey_px: f64,
            patch_scale: f64,
            gain_range: f64,
            flags: i32,
            edges: *const f64,
            out: *mut f64,
            hist: *mut u64,
        );
        fn modelflow_emu_sum_triangles(
            recs: *const f64,
            ranges: *const u32,
            ntri: i32,
            system: i32,
            scalars: *mut f64,
            blocks: *mut f64,
        );
    }

    pub(super) fn evaluate(
        h: &HostInputs,
        pixels: &[f32],
        images: &[f32],
        xs: &[f64],
        k: &KernelScalars,
    ) -> Sums {
        let mut recs = vec![0.0f64; REC * h.npatches];
        let mut hist = vec![0u64; crate::tracker::solve::HISTOGRAM_BINS];
        let mut scalars = vec![0.0f64; 4 * h.ntri];
        let mut blocks = vec![0.0f64; BLOCKS * h.ntri];
        // SAFETY: the slices hold what the C functions read and write (sizes as above and as
        // at upload), and the pointers live across the calls.
        unsafe {
            modelflow_emu_evaluate_patches(
                xs.as_ptr(),
                h.x0.as_ptr(),
                h.prev.as_ptr(),
                h.proj.as_ptr(),
                h.lag.as_ptr(),
                h.gap,
                h.tris.as_ptr(),
                h.patches.as_ptr(),
                h.weights.as_ptr(),
                pixels.as_ptr(),
                images.as_ptr(),
                h.img_off.as_ptr(),
                h.img_size.as_ptr(),
                h.npatches as i32,
                k.huber,
                k.tukey_px,
                k.patch_scale,
                k.gain_range,
                k.flags,
                h.edges.as_ptr(),
                recs.as_mut_ptr(),
                hist.as_mut_ptr(),
            );
            modelflow_emu_sum_triangles(
                recs.as_ptr(),
                h.ranges.as_ptr(),
                h.ntri as i32,
                i32::from(k.system),
                scalars.as_mut_ptr(),
                blocks.as_mut_ptr(),
            );
        }
        Sums {
            scalars,
            blocks: if k.system { blocks } else { Vec::new() },
            hist: (k.flags & super::FLAG_HIST != 0).then_some(hist),
        }
    }
}
