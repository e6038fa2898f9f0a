//! Compiles the GPU kernels as C (`src/tracker/gpu/emulate.c`, with the C compiler Rust links
//! with), so that the tests run their arithmetic against the CPU path on machines without a
//! GPU. The GPU itself compiles them at run time (NVRTC); nothing here needs CUDA.

fn main() {
    println!("cargo:rerun-if-changed=src/tracker/gpu/kernel.cu");
    println!("cargo:rerun-if-changed=src/tracker/gpu/pcg.cu");
    println!("cargo:rerun-if-changed=src/tracker/gpu/emulate.c");
    cc::Build::new()
        .std("c99")
        .file("src/tracker/gpu/emulate.c")
        // The CPU path's arithmetic, operation for operation: no contraction into fused
        // multiply-adds, no fast math.
        .flag_if_supported("-ffp-contract=off")
        .flag_if_supported("-fno-fast-math")
        .warnings(false)
        .compile("modelflow_gpu_emulated");
}
