//! The linear solve on the GPU: the conjugate gradients of `sparse::solve_pcg` with the system,
//! its vectors and the multilevel preconditioner's application on the device (`pcg.cu`). The
//! loop itself is `sparse::cg_loop`, the CPU's, driving [`CgOps`] here: so the two paths take
//! the same decisions, and since every operation is the CPU's to the bit (rows, groups and dot
//! products' runs summed in the CPU's order) they return the same step. The preconditioner is
//! built on the CPU (block inverses, the coarsest level's dense inverse) and uploaded with the
//! matrix, once per solve; each iteration reads back three dot products' run sums (a few
//! hundred doubles) and nothing else.
//!
//! Invariant: no I/O; a failure on the device is an [`Error::Gpu`] and the caller solves on the
//! CPU instead.

use super::{Backend, Gpu};
use crate::error::{Error, Result};
use crate::tracker::sparse::{
    cg_loop, flat_vectors, BlockSparse, CgOps, CgStop, CgSummary, CgVec, FlatSystem, DOT_RUN,
};
use nalgebra::Vector3;

/// How a dot product of `n` rows is cut into runs (see `sparse::dot`): runs of `DOT_RUN` rows
/// (at least one run).
fn dot_runs(n: usize) -> (usize, usize) {
    (DOT_RUN, n.div_ceil(DOT_RUN).max(1))
}

/// The runs' sums added as `sparse::dot` adds them: in order.
fn sum_runs(runs: &[f64]) -> f64 {
    runs.iter().sum()
}

impl Gpu {
    /// Whether a system of `rows` rows is solved here rather than on the CPU: from
    /// `solve_from` rows on (small systems cost the GPU more in launches than they save).
    pub(crate) fn solves(&self, rows: usize) -> bool {
        rows >= self.solve_from
    }

    /// `sparse::solve_pcg_until(a, b, stop)` on the GPU: the same solution to the bit.
    pub(crate) fn solve_pcg(
        &self,
        a: &BlockSparse,
        b: &[Vector3<f64>],
        stop: CgStop,
    ) -> Result<(Vec<Vector3<f64>>, CgSummary)> {
        if b.len() != a.dim() {
            return Err(Error::Gpu(format!(
                "linear solve: {} rows but a right-hand side of {}",
                a.dim(),
                b.len()
            )));
        }
        // The kernels index rows and entries with 32-bit integers.
        if 3 * a.dim() > i32::MAX as usize || a.entries() > u32::MAX as usize {
            return Err(Error::Gpu(format!(
                "linear solve: {} rows are more than the kernels index",
                a.dim()
            )));
        }
        let t0 = std::time::Instant::now();
        let sys = a.flat();
        let setup;
        let (x, summary) = match &self.backend {
            Backend::Cuda(c) => {
                let mut ops = c.cg_upload(&sys, flat_vectors(b))?;
                setup = t0.elapsed().as_secs_f64();
                let summary = cg_loop(&mut ops, stop)?;
                (ops.x()?, summary)
            }
            #[cfg(test)]
            Backend::Emulated => {
                let mut ops = emulated::EmuCg::new(&sys, flat_vectors(b));
                setup = t0.elapsed().as_secs_f64();
                let summary = match cg_loop(&mut ops, stop) {
                    Ok(s) => s,
                    Err(never) => match never {},
                };
                (ops.x, summary)
            }
        };
        let x = x
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect();
        let seconds = t0.elapsed().as_secs_f64();
        self.record(|s| {
            s.linear_solves += 1;
            s.cg_iterations += summary.iterations as u64;
            s.linear_solve_seconds += seconds;
            s.linear_setup_seconds += setup;
        });
        Ok((x, summary))
    }
}

/// What both backends upload of a [`FlatSystem`]: the levels in the order the preconditioner
/// runs them.
struct Levels<'s> {
    /// Every level (the coarsest last): its groups' children (starts, children) and count.
    gather: Vec<(&'s [u32], &'s [u32], usize)>,
    /// The intermediate levels' inverses (nine per group), and where each level's corrections
    /// start in the concatenated corrections (doubles).
    inverses: Vec<&'s [f64]>,
    rl_off: Vec<u64>,
    rl_len: usize,
    /// Every level's vertex-to-group map, level after level (the coarsest last).
    of: Vec<u32>,
    /// The coarsest level's inverse and size.
    coarse: Option<(&'s [f64], usize)>,
}

impl<'s> Levels<'s> {
    fn of(sys: &'s FlatSystem<'_>) -> Self {
        let mut out = Levels {
            gather: Vec::new(),
            inverses: Vec::new(),
            rl_off: Vec::new(),
            rl_len: 0,
            of: Vec::with_capacity(sys.n * (sys.levels.len() + 1)),
            coarse: None,
        };
        for l in &sys.levels {
            out.gather.push((l.starts, l.vertices, l.groups));
            out.inverses.push(&l.inverses);
            out.rl_off.push(out.rl_len as u64);
            out.rl_len += 3 * l.groups;
            out.of.extend_from_slice(l.of);
        }
        if let Some((l, inv, m)) = &sys.coarsest {
            out.gather.push((l.starts, l.vertices, l.groups));
            out.of.extend_from_slice(l.of);
            out.coarse = Some((inv, *m));
        }
        out
    }
}

/// The CUDA side: the system's buffers on the device and the kernels that run [`CgOps`].
pub(super) mod cuda {
    use super::{dot_runs, sum_runs, CgOps, CgVec, Error, FlatSystem, Levels, Result};
    use cudarc::driver::{
        CudaFunction, CudaModule, CudaSlice, CudaStream, LaunchConfig, PushKernelArg,
    };
    use std::sync::Arc;

    /// The CG kernels of one loaded module.
    pub(in crate::tracker::gpu) struct CgKernels {
        mul: CudaFunction,
        dot_runs: CudaFunction,
        step: CudaFunction,
        update_p: CudaFunction,
        gather: CudaFunction,
        level: CudaFunction,
        coarse: CudaFunction,
        precondition: CudaFunction,
    }

    fn gpu_err(what: &str) -> impl Fn(cudarc::driver::DriverError) -> Error + '_ {
        move |e| Error::Gpu(format!("linear solve: {what}: {e}"))
    }

    impl CgKernels {
        pub(in crate::tracker::gpu) fn load(module: &Arc<CudaModule>) -> Result<Self> {
            let f = |name: &str| {
                module
                    .load_function(name)
                    .map_err(|e| Error::Gpu(format!("loading {name}: {e}")))
            };
            Ok(CgKernels {
                mul: f("cg_mul")?,
                dot_runs: f("cg_dot_runs")?,
                step: f("cg_step")?,
                update_p: f("cg_update_p")?,
                gather: f("cg_gather")?,
                level: f("cg_level")?,
                coarse: f("cg_coarse")?,
                precondition: f("cg_precondition")?,
            })
        }
    }

    /// One solve's system and vectors on the device.
    pub(in crate::tracker::gpu) struct CudaCg<'k> {
        stream: Arc<CudaStream>,
        k: &'k CgKernels,
        n: i32,
        row_ptr: CudaSlice<u32>,
        cols: CudaSlice<u32>,
        blocks: CudaSlice<f64>,
        k_ptr: CudaSlice<u32>,
        k_cols: CudaSlice<u32>,
        k_vals: CudaSlice<f64>,
        s: f64,
        has_scalar: i32,
        fine: CudaSlice<f64>,
        of: CudaSlice<u32>,
        /// Every level's groups' children (starts, children), count and residuals.
        gather: Vec<(CudaSlice<u32>, CudaSlice<u32>, i32)>,
        gathered: Vec<CudaSlice<f64>>,
        inverses: Vec<CudaSlice<f64>>,
        rl: CudaSlice<f64>,
        rl_off: Vec<u64>,
        rl_off_dev: CudaSlice<u64>,
        /// The coarsest level's inverse and size.
        coarse: Option<(CudaSlice<f64>, i32)>,
        r0: CudaSlice<f64>,
        b: CudaSlice<f64>,
        x: CudaSlice<f64>,
        r: CudaSlice<f64>,
        z: CudaSlice<f64>,
        p: CudaSlice<f64>,
        ap: CudaSlice<f64>,
        runs: CudaSlice<f64>,
    }

    /// Threads per block of the per-row kernels.
    const THREADS: u32 = 128;

    fn rows(n: usize) -> LaunchConfig {
        LaunchConfig {
            grid_dim: ((n as u32).div_ceil(THREADS).max(1), 1, 1),
            block_dim: (THREADS, 1, 1),
            shared_mem_bytes: 0,
        }
    }

    impl super::super::cuda::Cuda {
        /// Uploads a system, its preconditioner and its right-hand side.
        pub(in crate::tracker::gpu) fn cg_upload<'k>(
            &'k self,
            sys: &FlatSystem<'_>,
            b: &[f64],
        ) -> Result<CudaCg<'k>> {
            let st = &self.stream;
            let n = sys.n;
            let (k_ptr, k_cols, k_vals, s) = match &sys.scalar {
                Some((p, c, v, s)) => (&p[..], *c, *v, *s),
                None => (&[][..], &[][..], &[][..], 0.0),
            };
            let lv = Levels::of(sys);
            let mut gather = Vec::with_capacity(lv.gather.len());
            let mut gathered = Vec::with_capacity(lv.gather.len());
            for &(starts, children, groups) in &lv.gather {
                gather.push((
                    self.up(starts, "uploading the levels' groups")?,
                    self.up(children, "uploading the levels' groups")?,
                    groups as i32,
                ));
                gathered.push(self.zeros(3 * groups, "allocating the levels' residuals")?);
            }
            let inverses = lv
                .inverses
                .iter()
                .map(|inv| self.up(inv, "uploading the levels' inverses"))
                .collect::<Result<Vec<_>>>()?;
            let coarse = match lv.coarse {
                Some((inv, m)) => Some((
                    self.up(inv, "uploading the coarsest level's inverse")?,
                    m as i32,
                )),
                None => None,
            };
            let m = lv.coarse.map_or(0, |c| c.1);
            let (_, runs) = dot_runs(n);
            let bd = self.up(b, "uploading the right-hand side")?;
            Ok(CudaCg {
                stream: Arc::clone(st),
                k: &self.cg,
                n: n as i32,
                row_ptr: self.up(&sys.row_ptr, "uploading the matrix")?,
                cols: self.up(sys.cols, "uploading the matrix")?,
                blocks: self.up(sys.blocks, "uploading the matrix")?,
                k_ptr: self.up(k_ptr, "uploading the scalar part")?,
                k_cols: self.up(k_cols, "uploading the scalar part")?,
                k_vals: self.up(k_vals, "uploading the scalar part")?,
                s,
                has_scalar: i32::from(sys.scalar.is_some()),
                fine: self.up(&sys.fine, "uploading block-Jacobi's inverses")?,
                of: self.up(&lv.of, "uploading the levels' groups")?,
                gather,
                gathered,
                inverses,
                rl: self.zeros(lv.rl_len, "allocating the levels' corrections")?,
                rl_off_dev: self.up(&lv.rl_off, "uploading the levels' offsets")?,
                rl_off: lv.rl_off,
                coarse,
                r0: self.zeros(m, "allocating the coarsest level's correction")?,
                x: self.zeros(3 * n, "allocating x")?,
                r: self.zeros(3 * n, "allocating r")?,
                z: self.zeros(3 * n, "allocating z")?,
                p: self.zeros(3 * n, "allocating p")?,
                ap: self.zeros(3 * n, "allocating Ap")?,
                runs: self.zeros(runs, "allocating the dot products' runs")?,
                b: bd,
            })
        }
    }

    impl CudaCg<'_> {
        pub(in crate::tracker::gpu) fn x(&self) -> Result<Vec<f64>> {
            self.stream
                .clone_dtoh(&self.x)
                .map_err(gpu_err("reading the solution"))
        }

        fn vec(&self, v: CgVec) -> &CudaSlice<f64> {
            match v {
                CgVec::B => &self.b,
                CgVec::R => &self.r,
                CgVec::Z => &self.z,
                CgVec::P => &self.p,
                CgVec::Ap => &self.ap,
            }
        }
    }

    impl CgOps for CudaCg<'_> {
        type Error = Error;

        fn dot(&mut self, a: CgVec, b: CgVec) -> Result<f64> {
            let (run, runs) = dot_runs(self.n as usize);
            let (n, run_i, runs_i) = (self.n, run as i32, runs as i32);
            let mut l = self.stream.launch_builder(&self.k.dot_runs);
            l.arg(self.vec(a))
                .arg(self.vec(b))
                .arg(&n)
                .arg(&run_i)
                .arg(&runs_i)
                .arg(&self.runs);
            // SAFETY: the arguments match `cg_dot_runs`; both vectors hold 3n doubles and
            // `runs` at least `runs`.
            unsafe { l.launch(rows(runs)) }.map_err(gpu_err("cg_dot_runs"))?;
            let host = self
                .stream
                .clone_dtoh(&self.runs.slice(0..runs))
                .map_err(gpu_err("reading a dot product"))?;
            Ok(sum_runs(&host))
        }

        fn start(&mut self) -> Result<()> {
            self.stream
                .memcpy_dtod(&self.b, &mut self.r)
                .map_err(gpu_err("r = b"))?;
            self.precondition()?;
            self.stream
                .memcpy_dtod(&self.z, &mut self.p)
                .map_err(gpu_err("p = z"))
        }

        fn mul_p(&mut self) -> Result<()> {
            let mut l = self.stream.launch_builder(&self.k.mul);
            l.arg(&self.row_ptr)
                .arg(&self.cols)
                .arg(&self.blocks)
                .arg(&self.k_ptr)
                .arg(&self.k_cols)
                .arg(&self.k_vals)
                .arg(&self.s)
                .arg(&self.has_scalar)
                .arg(&self.p)
                .arg(&mut self.ap)
                .arg(&self.n);
            // SAFETY: the arguments match `cg_mul`, and the buffers hold the system uploaded.
            unsafe { l.launch(rows(self.n as usize)) }.map_err(gpu_err("cg_mul"))?;
            Ok(())
        }

        fn step(&mut self, alpha: f64) -> Result<()> {
            let n3 = 3 * self.n;
            let mut l = self.stream.launch_builder(&self.k.step);
            l.arg(&mut self.x)
                .arg(&mut self.r)
                .arg(&self.p)
                .arg(&self.ap)
                .arg(&alpha)
                .arg(&n3);
            // SAFETY: the arguments match `cg_step`; every vector holds 3n doubles.
            unsafe { l.launch(rows(n3 as usize)) }.map_err(gpu_err("cg_step"))?;
            Ok(())
        }

        fn precondition(&mut self) -> Result<()> {
            for lv in 0..self.gather.len() {
                let (starts, children, groups) = &self.gather[lv];
                let (below, this) = self.gathered.split_at_mut(lv);
                let src = if lv == 0 { &self.r } else { &below[lv - 1] };
                let mut l = self.stream.launch_builder(&self.k.gather);
                l.arg(starts)
                    .arg(children)
                    .arg(src)
                    .arg(&mut this[0])
                    .arg(groups);
                // SAFETY: the arguments match `cg_gather`; the residuals hold 3 doubles per
                // group, the children index the level below.
                unsafe { l.launch(rows(*groups as usize)) }.map_err(gpu_err("cg_gather"))?;
            }
            for (lv, inv) in self.inverses.iter().enumerate() {
                let groups = self.gather[lv].2;
                let mut rl = self.rl.slice_mut(self.rl_off[lv] as usize..);
                let mut l = self.stream.launch_builder(&self.k.level);
                l.arg(inv).arg(&self.gathered[lv]).arg(&mut rl).arg(&groups);
                // SAFETY: the arguments match `cg_level`; `rl` has 3 doubles per group.
                unsafe { l.launch(rows(groups as usize)) }.map_err(gpu_err("cg_level"))?;
            }
            if let Some((inv, m)) = &self.coarse {
                let gathered = self
                    .gathered
                    .last()
                    .expect("the coarsest level's residuals");
                let mut l = self.stream.launch_builder(&self.k.coarse);
                l.arg(inv).arg(m).arg(gathered).arg(&mut self.r0);
                // SAFETY: the arguments match `cg_coarse`; `r0` holds m doubles, the inverse m².
                unsafe { l.launch(rows(*m as usize)) }.map_err(gpu_err("cg_coarse"))?;
            }
            let levels = self.inverses.len() as i32;
            let has_coarse = i32::from(self.coarse.is_some());
            let mut l = self.stream.launch_builder(&self.k.precondition);
            l.arg(&self.fine)
                .arg(&self.r)
                .arg(&self.of)
                .arg(&self.rl)
                .arg(&self.rl_off_dev)
                .arg(&levels)
                .arg(&has_coarse)
                .arg(&self.r0)
                .arg(&mut self.z)
                .arg(&self.n);
            // SAFETY: the arguments match `cg_precondition`; `of` holds n entries per level.
            unsafe { l.launch(rows(self.n as usize)) }.map_err(gpu_err("cg_precondition"))?;
            Ok(())
        }

        fn update_p(&mut self, beta: f64) -> Result<()> {
            let n3 = 3 * self.n;
            let mut l = self.stream.launch_builder(&self.k.update_p);
            l.arg(&mut self.p).arg(&self.z).arg(&beta).arg(&n3);
            // SAFETY: the arguments match `cg_update_p`.
            unsafe { l.launch(rows(n3 as usize)) }.map_err(gpu_err("cg_update_p"))?;
            Ok(())
        }
    }
}

/// The CG kernels compiled as C (`emulate.c`), for the tests.
#[cfg(test)]
mod emulated {
    use super::{dot_runs, sum_runs, CgOps, CgVec, FlatSystem, Levels};

    unsafe extern "C" {
        fn modelflow_emu_cg_mul(
            row_ptr: *const u32,
            cols: *const u32,
            blocks: *const f64,
            k_ptr: *const u32,
            k_cols: *const u32,
            k_vals: *const f64,
            s: f64,
            has_scalar: i32,
            x: *const f64,
            y: *mut f64,
            n: i32,
        );
        fn modelflow_emu_cg_dot_runs(
            a: *const f64,
            b: *const f64,
            n: i32,
            run: i32,
            runs: i32,
            out: *mut f64,
        );
        fn modelflow_emu_cg_step(
            x: *mut f64,
            r: *mut f64,
            p: *const f64,
            ap: *const f64,
            alpha: f64,
            n3: i32,
        );
        fn modelflow_emu_cg_update_p(p: *mut f64, z: *const f64, beta: f64, n3: i32);
        fn modelflow_emu_cg_gather(
            starts: *const u32,
            children: *const u32,
            src: *const f64,
            dst: *mut f64,
            groups: i32,
        );
        fn modelflow_emu_cg_level(inv: *const f64, gathered: *const f64, rl: *mut f64, groups: i32);
        fn modelflow_emu_cg_coarse(inv: *const f64, m: i32, gathered: *const f64, r0: *mut f64);
        fn modelflow_emu_cg_precondition(
            fine: *const f64,
            r: *const f64,
            of: *const u32,
            rl: *const f64,
            rl_off: *const u64,
            levels: i32,
            has_coarse: i32,
            r0: *const f64,
            z: *mut f64,
            n: i32,
        );
    }

    /// [`CgOps`] through the emulated kernels, on host memory.
    pub(super) struct EmuCg {
        n: usize,
        row_ptr: Vec<u32>,
        cols: Vec<u32>,
        blocks: Vec<f64>,
        scalar: (Vec<u32>, Vec<u32>, Vec<f64>, f64, i32),
        fine: Vec<f64>,
        of: Vec<u32>,
        gather: Vec<(Vec<u32>, Vec<u32>, usize)>,
        gathered: Vec<Vec<f64>>,
        inverses: Vec<Vec<f64>>,
        rl: Vec<f64>,
        rl_off: Vec<u64>,
        coarse: Option<(Vec<f64>, usize)>,
        r0: Vec<f64>,
        b: Vec<f64>,
        pub x: Vec<f64>,
        r: Vec<f64>,
        z: Vec<f64>,
        p: Vec<f64>,
        ap: Vec<f64>,
    }

    impl EmuCg {
        pub(super) fn new(sys: &FlatSystem<'_>, b: &[f64]) -> Self {
            let n = sys.n;
            let lv = Levels::of(sys);
            let scalar = match &sys.scalar {
                Some((p, c, v, s)) => (p.clone(), c.to_vec(), v.to_vec(), *s, 1),
                None => (vec![0], vec![0], vec![0.0], 0.0, 0),
            };
            let m = lv.coarse.map_or(0, |c| c.1);
            EmuCg {
                n,
                row_ptr: sys.row_ptr.clone(),
                cols: sys.cols.to_vec(),
                blocks: sys.blocks.to_vec(),
                scalar,
                fine: sys.fine.clone(),
                of: lv.of,
                gathered: lv.gather.iter().map(|g| vec![0.0; 3 * g.2]).collect(),
                gather: lv
                    .gather
                    .iter()
                    .map(|&(s, c, g)| (s.to_vec(), c.to_vec(), g))
                    .collect(),
                inverses: lv.inverses.iter().map(|i| i.to_vec()).collect(),
                rl: vec![0.0; lv.rl_len.max(1)],
                rl_off: lv.rl_off,
                coarse: lv.coarse.map(|(i, m)| (i.to_vec(), m)),
                r0: vec![0.0; m.max(1)],
                b: b.to_vec(),
                x: vec![0.0; 3 * n],
                r: vec![0.0; 3 * n],
                z: vec![0.0; 3 * n],
                p: vec![0.0; 3 * n],
                ap: vec![0.0; 3 * n],
            }
        }

        fn vec(&self, v: CgVec) -> &[f64] {
            match v {
                CgVec::B => &self.b,
                CgVec::R => &self.r,
                CgVec::Z => &self.z,
                CgVec::P => &self.p,
                CgVec::Ap => &self.ap,
            }
        }
    }

    impl CgOps for EmuCg {
        type Error = std::convert::Infallible;

        fn dot(&mut self, a: CgVec, b: CgVec) -> Result<f64, Self::Error> {
            let (run, runs) = dot_runs(self.n);
            let mut out = vec![0.0; runs];
            // SAFETY: both vectors hold 3n doubles, `out` `runs`.
            unsafe {
                modelflow_emu_cg_dot_runs(
                    self.vec(a).as_ptr(),
                    self.vec(b).as_ptr(),
                    self.n as i32,
                    run as i32,
                    runs as i32,
                    out.as_mut_ptr(),
                )
            };
            Ok(sum_runs(&out))
        }

        fn start(&mut self) -> Result<(), Self::Error> {
            self.r.copy_from_slice(&self.b);
            self.precondition()?;
            self.p.copy_from_slice(&self.z);
            Ok(())
        }

        fn mul_p(&mut self) -> Result<(), Self::Error> {
            let (kp, kc, kv, s, has) = &self.scalar;
            // SAFETY: the arrays are the flattened system of `n` rows.
            unsafe {
                modelflow_emu_cg_mul(
                    self.row_ptr.as_ptr(),
                    self.cols.as_ptr(),
                    self.blocks.as_ptr(),
                    kp.as_ptr(),
                    kc.as_ptr(),
                    kv.as_ptr(),
                    *s,
                    *has,
                    self.p.as_ptr(),
                    self.ap.as_mut_ptr(),
                    self.n as i32,
                )
            };
            Ok(())
        }

        fn step(&mut self, alpha: f64) -> Result<(), Self::Error> {
            // SAFETY: every vector holds 3n doubles.
            unsafe {
                modelflow_emu_cg_step(
                    self.x.as_mut_ptr(),
                    self.r.as_mut_ptr(),
                    self.p.as_ptr(),
                    self.ap.as_ptr(),
                    alpha,
                    3 * self.n as i32,
                )
            };
            Ok(())
        }

        fn precondition(&mut self) -> Result<(), Self::Error> {
            for lv in 0..self.gather.len() {
                let (starts, children, groups) = &self.gather[lv];
                let (below, this) = self.gathered.split_at_mut(lv);
                let src = if lv == 0 { &self.r } else { &below[lv - 1] };
                // SAFETY: the residuals hold 3 doubles per group; the children index the
                // level below.
                unsafe {
                    modelflow_emu_cg_gather(
                        starts.as_ptr(),
                        children.as_ptr(),
                        src.as_ptr(),
                        this[0].as_mut_ptr(),
                        *groups as i32,
                    )
                };
            }
            for (lv, inv) in self.inverses.iter().enumerate() {
                let off = self.rl_off[lv] as usize;
                // SAFETY: `rl` holds 3 doubles per group of every level.
                unsafe {
                    modelflow_emu_cg_level(
                        inv.as_ptr(),
                        self.gathered[lv].as_ptr(),
                        self.rl[off..].as_mut_ptr(),
                        self.gather[lv].2 as i32,
                    )
                };
            }
            if let Some((inv, m)) = &self.coarse {
                let gathered = self
                    .gathered
                    .last()
                    .expect("the coarsest level's residuals");
                // SAFETY: `r0` holds m doubles, `inv` m².
                unsafe {
                    modelflow_emu_cg_coarse(
                        inv.as_ptr(),
                        *m as i32,
                        gathered.as_ptr(),
                        self.r0.as_mut_ptr(),
                    )
                };
            }
            // SAFETY: `of` holds n entries per level (and the coarsest).
            unsafe {
                modelflow_emu_cg_precondition(
                    self.fine.as_ptr(),
                    self.r.as_ptr(),
                    self.of.as_ptr(),
                    self.rl.as_ptr(),
                    self.rl_off.as_ptr(),
                    self.inverses.len() as i32,
                    i32::from(self.coarse.is_some()),
                    self.r0.as_ptr(),
                    self.z.as_mut_ptr(),
                    self.n as i32,
                )
            };
            Ok(())
        }

        fn update_p(&mut self, beta: f64) -> Result<(), Self::Error> {
            // SAFETY: both vectors hold 3n doubles.
            unsafe {
                modelflow_emu_cg_update_p(
                    self.p.as_mut_ptr(),
                    self.z.as_ptr(),
                    beta,
                    3 * self.n as i32,
                )
            };
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Gpu;
    use crate::tracker::sparse::{solve_pcg, solve_pcg_until, BlockSparse, CgStop, ScalarSparse};
    use nalgebra::{Matrix3, Vector3};
    use std::sync::Arc;

    /// A `w × h` grid's system as the tracker builds one: symmetric positive 3×3 edge terms
    /// that differ per edge, a scalar part `s·LᵀL` (an umbrella Laplacian, as bending adds),
    /// Levenberg–Marquardt damping; and a right-hand side.
    fn grid_system(w: u32, h: u32) -> (BlockSparse, Vec<Vector3<f64>>) {
        let n = (w * h) as usize;
        // The grid's edges and one diagonal per square: a triangulated grid.
        let mut edges = crate::tracker::sparse::tests::grid_edges(w, h);
        for y in 0..h - 1 {
            edges.extend((0..w - 1).map(|x| [y * w + x, y * w + x + w + 1]));
        }
        let mut a = BlockSparse::new(n, &edges);
        for (e, &[i, j]) in edges.iter().enumerate() {
            let t = e as f64 * 0.37;
            let d = Vector3::new(t.sin(), t.cos(), 0.3 + 0.1 * (2.0 * t).sin());
            let k = Matrix3::identity() * (1.0 + 0.5 * t.sin()) + d * d.transpose() * 0.7;
            a.add_edge(e, [i as usize, j as usize], &k);
        }
        let mut nb: Vec<Vec<u32>> = vec![Vec::new(); n];
        for &[i, j] in &edges {
            nb[i as usize].push(j);
            nb[j as usize].push(i);
        }
        let rows: Vec<Vec<(u32, f64)>> = (0..n)
            .map(|i| {
                let mut row = vec![(i as u32, 1.0)];
                let c = -1.0 / nb[i].len() as f64;
                row.extend(nb[i].iter().map(|&j| (j, c)));
                row
            })
            .collect();
        let k = Arc::new(ScalarSparse::gram(n, rows.iter().map(|r| &r[..])));
        a.add_scalar(&k, 0.3);
        a.damp(0.01, 0.05);
        let b = (0..n)
            .map(|i| {
                let t = i as f64;
                Vector3::new((t * 0.01).sin(), ((i % 13) as f64) - 6.0, (t * 0.003).cos())
            })
            .collect();
        (a, b)
    }

    /// The emulated kernels (`pcg.cu` compiled as C) through the GPU path's host side give
    /// the CPU's solution to the bit, with the same iterations: on a system past
    /// `PARALLEL_ROWS` (many dot-product runs, several coarse levels) and on a small one (two
    /// runs, one level), converged, stopped at the iteration cap, and stopped by the early
    /// verdict on an unpromising step.
    #[test]
    fn the_gpu_conjugate_gradients_give_the_cpus_solution_to_the_bit() {
        let gpu = Gpu::emulated();
        for (w, h) in [(80, 70), (12, 9)] {
            let (a, b) = grid_system(w, h);
            let flat = a.flat();
            assert!(
                !flat.levels.is_empty() || w < 20,
                "{w}×{h}: no coarse levels"
            );
            assert!(flat.coarsest.is_some(), "{w}×{h}: no coarsest level");
            for (tol, max) in [(1e-10, 1000), (1e-3, 200), (1e-12, 5)] {
                let (x_cpu, s_cpu) = solve_pcg(&a, &b, tol, max);
                let (x_gpu, s_gpu) = gpu.solve_pcg(&a, &b, CgStop::residual(tol, max)).unwrap();
                assert!(s_cpu.iterations > 2, "{w}×{h}: {s_cpu:?}");
                assert_eq!(s_cpu, s_gpu, "{w}×{h}, tol {tol}, max {max}");
                assert!(
                    x_cpu.iter().zip(&x_gpu).all(|(p, q)| p == q),
                    "{w}×{h}, tol {tol}: the solutions differ"
                );
            }
            // The early verdict on an unpromising step: the same iteration, the same bits.
            let (_, full) = solve_pcg(&a, &b, 1e-3, 200);
            let stop = CgStop {
                unpromising_below: Some(3.0 * full.decrease),
                ..CgStop::residual(1e-3, 200)
            };
            let (x_cpu, s_cpu) = solve_pcg_until(&a, &b, stop);
            let (x_gpu, s_gpu) = gpu.solve_pcg(&a, &b, stop).unwrap();
            assert!(s_cpu.unpromising, "{w}×{h}: {s_cpu:?}");
            assert_eq!(s_cpu, s_gpu, "{w}×{h}, stopped early");
            assert!(x_cpu.iter().zip(&x_gpu).all(|(p, q)| p == q));
        }
        let st = gpu.stats();
        assert_eq!(st.linear_solves, 8);
        assert!(st.cg_iterations > 20, "{st:?}");
    }

    /// The loop's edge cases on the emulated GPU, equal to the CPU's: a zero right-hand side
    /// (no iteration), a zero matrix (the coarsest level's Cholesky fails, `pᵀAp = 0` stops the
    /// loop), a mesh of many separate pieces (aggregation stops above the dense level's size:
    /// every level block-Jacobi); and a right-hand side of the wrong length refused.
    #[test]
    fn the_gpu_conjugate_gradients_handle_what_the_cpu_handles() {
        let gpu = Gpu::emulated();
        let same = |a: &BlockSparse, b: &[Vector3<f64>], what: &str| {
            let (x_cpu, s_cpu) = solve_pcg(a, b, 1e-8, 300);
            let (x_gpu, s_gpu) = gpu.solve_pcg(a, b, CgStop::residual(1e-8, 300)).unwrap();
            assert_eq!(s_cpu, s_gpu, "{what}");
            assert!(x_cpu.iter().zip(&x_gpu).all(|(p, q)| p == q), "{what}");
            s_cpu
        };
        let (a, b) = grid_system(30, 20);
        let zero_b = vec![Vector3::zeros(); b.len()];
        assert_eq!(same(&a, &zero_b, "zero b").iterations, 0);
        let edges = crate::tracker::sparse::tests::grid_edges(30, 20);
        let zero_a = BlockSparse::new(600, &edges);
        assert!(
            zero_a.flat().coarsest.is_none(),
            "a zero matrix has no factor"
        );
        assert_eq!(same(&zero_a, &b, "zero A").iterations, 0);
        // 400 separate triangles: each ends as one group, far more than the dense level takes.
        let n = 1200;
        let tris: Vec<[u32; 2]> = (0..400u32)
            .flat_map(|t| {
                [
                    [3 * t, 3 * t + 1],
                    [3 * t + 1, 3 * t + 2],
                    [3 * t, 3 * t + 2],
                ]
            })
            .collect();
        let mut pieces = BlockSparse::new(n, &tris);
        for (e, &[i, j]) in tris.iter().enumerate() {
            let k = Matrix3::identity() * (1.0 + 0.3 * (e as f64).sin());
            pieces.add_edge(e, [i as usize, j as usize], &k);
        }
        pieces.damp(1e-3, 0.01);
        let flat = pieces.flat();
        assert!(flat.coarsest.is_none() && !flat.levels.is_empty());
        let rhs: Vec<Vector3<f64>> = (0..n)
            .map(|i| Vector3::new((i as f64).sin(), 1.0, (i % 7) as f64))
            .collect();
        let s = same(&pieces, &rhs, "separate pieces");
        assert!(s.relative_residual <= 1e-8, "{s:?}");
        assert!(gpu
            .solve_pcg(&a, &b[1..], CgStop::residual(1e-8, 10))
            .is_err());
    }

    /// On a machine with an NVIDIA GPU, the same on the device (`pcg.cu` compiled by NVRTC, run
    /// in parallel): the CPU's solution to the bit. Without a GPU (CI) it is skipped and says
    /// why.
    #[test]
    fn the_conjugate_gradients_on_a_gpu_give_the_cpus_solution_to_the_bit() {
        let gpu = match Gpu::open() {
            Ok(g) => g,
            Err(e) => {
                eprintln!("SKIPPED (no GPU here): {e}");
                return;
            }
        };
        for (w, h) in [(200, 200), (80, 70), (12, 9)] {
            let (a, b) = grid_system(w, h);
            for (tol, max) in [(1e-10, 1000), (1e-3, 200)] {
                let t = std::time::Instant::now();
                let (x_cpu, s_cpu) = solve_pcg(&a, &b, tol, max);
                let cpu_s = t.elapsed().as_secs_f64();
                let t = std::time::Instant::now();
                drop(std::hint::black_box(a.flat()));
                let pre_s = t.elapsed().as_secs_f64();
                let before = gpu.stats();
                let t = std::time::Instant::now();
                let (x_gpu, s_gpu) = gpu.solve_pcg(&a, &b, CgStop::residual(tol, max)).unwrap();
                let gpu_s = t.elapsed().as_secs_f64();
                let st = gpu.stats().since(&before);
                eprintln!(
                    "{w}x{h}, tol {tol:e}: {} iterations; CPU {:.1} ms (preconditioner {:.1}), GPU {:.1} ms (set-up and upload {:.1}; {:.0} us per iteration)",
                    s_cpu.iterations,
                    cpu_s * 1e3,
                    pre_s * 1e3,
                    gpu_s * 1e3,
                    st.linear_setup_seconds * 1e3,
                    (gpu_s - st.linear_setup_seconds) * 1e6 / s_gpu.iterations.max(1) as f64
                );
                assert_eq!(s_cpu, s_gpu, "{w}×{h}, tol {tol}");
                assert!(
                    x_cpu.iter().zip(&x_gpu).all(|(p, q)| p == q),
                    "{w}×{h}, tol {tol}: the solutions differ"
                );
            }
        }
    }
}
