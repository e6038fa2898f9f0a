#!/usr/bin/env bash
# The GPU path's checks and timings on a machine with an NVIDIA GPU (docs/gpu.md, "Measured"),
# in one go: the equality tests on the device, a 40 000-vertex track on both paths compared
# byte for byte, and the benchmarks on both paths in the same minutes.
#
#   tools/gpu_check.sh [MODELFLOW_BINARY] [LIB_TEST_BINARY] [OUT_FOLDER]
#
# The binaries are built elsewhere (`cargo build --release`, `cargo test --release -p modelflow
# --lib --no-run`) and may be stripped; the GPU machine needs the NVIDIA driver and NVRTC only.
set -u
BIN=${1:-target/release/modelflow}
TESTS=${2:?the library test binary (cargo test --release -p modelflow --lib --no-run)}
OUT=${3:-/tmp/gpu-check}
mkdir -p "$OUT"
# NVRTC: CUDA's lib64, or the pip package's folder.
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib \
    $(python3 -c 'import nvidia.cuda_nvrtc as m, os; print(os.path.dirname(m.__file__) + "/lib")' 2>/dev/null); do
    [ -d "$d" ] && LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
export LD_LIBRARY_PATH
step() { echo; echo "=== $* ($(date +%T))"; }

step "device"
nvidia-smi -L
nproc

step "1. equality on the device (GPU tests; then the cloth with every linear solve on the GPU)"
"$TESTS" --test-threads 1 --nocapture gpu 2>&1 | tee "$OUT/tests.txt" | grep -E "^test |GPU|frame|iterations|SKIPPED|panicked|result"
MODELFLOW_GPU_SOLVE_FROM=0 "$TESTS" --nocapture the_gpu_tracks_the_default_cloth 2>&1 |
    tee "$OUT/tests-solve-all.txt" | grep -E "frame|panicked|result"

step "2. a 40 000-vertex cloth tracked on both paths, meshes compared byte for byte"
"$BIN" synth --cloth-grid 200 --frames 3 --out /tmp/c40k >/dev/null 2>&1
for dev in cpu gpu; do
    /usr/bin/time -f "$dev: %e s wall, %M KiB peak" "$BIN" track --scene /tmp/c40k/scene.json \
        --out "/tmp/c40k-$dev" --frames 0..2 --device $dev 2>&1 | tail -2
done
for f in 0001 0002; do
    cmp "/tmp/c40k-cpu/$f.obj" "/tmp/c40k-gpu/$f.obj" && echo "frame $f: identical"
done

step "3. the default cloth (bench, 30 frames): GPU, GPU with every solve there, CPU"
"$BIN" bench --frames 30 --device gpu 2>&1 | tee "$OUT/bench-gpu.txt" | grep -v "^bench [0-9]"
MODELFLOW_GPU_SOLVE_FROM=0 "$BIN" bench --frames 30 --device gpu 2>&1 | tee "$OUT/bench-gpu-all.txt" |
    grep -E "end to end|linear|per frame|solve"
"$BIN" bench --frames 30 2>&1 | tee "$OUT/bench-cpu.txt" | grep -E "end to end|linear|evaluations|solve"

step "4. cost-model points: 2 x 640x480 and 8 x 3840x2160, 40 000 vertices, GPU then CPU"
for size in "2 640x480" "8 3840x2160"; do
    set -- $size
    for dev in gpu cpu; do
        "$BIN" bench --scale --scale-cameras "$1" --scale-sizes "$2" --scale-vertices 40000 \
            --frames 3 --device $dev 2>&1 | tee "$OUT/scale-$1-$2-$dev.txt" | grep -vE "^scale [0-9]"
    done
done
step "done"
