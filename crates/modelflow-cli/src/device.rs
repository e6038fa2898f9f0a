//! `--device`: where the solver's per-pixel work runs (the CPU, or an NVIDIA GPU through the
//! library's `Gpu`), shared by `track` and `bench`.

use modelflow::tracker::Gpu;
use std::sync::Arc;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Device {
    /// This machine's cores (rayon).
    Cpu,
    /// The first NVIDIA GPU, through CUDA (driver and NVRTC loaded at run time; docs/gpu.md).
    Gpu,
}

#[derive(clap::Args, Clone, Copy)]
pub struct DeviceArgs {
    /// Where the solver's per-pixel work (warp, sample, loss, normal equations) runs: cpu, or
    /// gpu (an NVIDIA GPU with its driver and CUDA's NVRTC library; the meshes agree with the
    /// CPU's to rounding, see docs/gpu.md).
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    pub device: Device,
}

impl DeviceArgs {
    /// Opens the GPU when one was asked for (saying which on stderr); `None` for the CPU.
    pub fn open(&self) -> anyhow::Result<Option<Arc<Gpu>>> {
        match self.device {
            Device::Cpu => Ok(None),
            Device::Gpu => {
                let gpu = Gpu::open()?;
                eprintln!("solving on the GPU: {}", gpu.name());
                Ok(Some(Arc::new(gpu)))
            }
        }
    }
}
