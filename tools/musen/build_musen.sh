#!/usr/bin/env bash
# Build MUSEN's command-line simulator (cmusen) for the CPU only: no Qt, no CUDA toolkit.
# bondem's copy of shared/tools/musen/build_musen.sh (kept there for 1.70.0 as it was),
# extended to MUSEN's newer source layout (1.71 on: CMusen/, Models/, Modules/, Version/
# instead of MUSEN/ and GeneralFunctions/), so that MUSEN_COMMIT=v1.74.2 builds the
# current release the same way. Both layouts are found from the sources themselves.
#
# Usage: build_musen.sh [DEST] [SOURCE]
#   DEST    build folder (default /tmp/musen-build); the program ends up as DEST/cmusen
#   SOURCE  a MUSEN source tree, or a git directory of github.com/msolids/musen (bare is
#           fine; blobs missing from a partial copy are skipped, only sources are needed).
#           Default: $MUSEN_SOURCE, else DEST/src from an earlier run.
# Environment:
#   MUSEN_COMMIT  commit or tag taken from a git SOURCE (default 1547403d16..., "Release
#                 1.70.0"; v1.74.2 for the current release)
#   JOBS          parallel compile jobs (default 2); every compile runs under nice -n 19
#
# MUSEN's own Linux build (MUSEN_Linux/CMakeLists.txt) needs nvcc: its CMake project is
# "C CXX CUDA", the CLI target compiles the .cu files and calls the CUDA runtime. Debian
# main has no CUDA toolkit and PyPI has no nvcc binary (the nvidia-cuda-nvcc-cu12 wheel
# carries ptxas and headers only), so this recipe
#   * compiles every .cpp of the cmusen target (MUSEN/, GeneralFunctions/, Databases/
#     without QT_GUI, MMusen and the model templates) with g++ against the CUDA headers of
#     the PyPI wheels nvidia-cuda-runtime-cu12 (cuda_runtime.h, libcudart_static.a),
#     nvidia-cuda-nvcc-cu12 (crt/) and nvidia-cuda-cccl-cu12 (thrust/, used by two GPU
#     headers for member pointers only);
#   * leaves out the 17 .cu files (GPU kernels only), and
#   * resolves the symbols only they defined with generated stubs that abort with a
#     message: they are reachable only through SIMULATOR_TYPE GPU, which this build must
#     not be asked for. The CPU code (models, CPUSimulator, generators, I/O) is MUSEN's,
#     unmodified, compiled with MUSEN's flags (-O3 -pthread -fPIC, C++17, its defines).
# Idempotent: rerunning reuses what is there.
set -euo pipefail

DEST=${1:-/tmp/musen-build}
SOURCE=${2:-${MUSEN_SOURCE:-}}
COMMIT=${MUSEN_COMMIT:-1547403d1616732d739533a81e6658c6c971dedb}
JOBS=${JOBS:-2}
NICE="nice -n 19"
mkdir -p "$DEST"
DEST=$(cd "$DEST" && pwd)
SRC=$DEST/src

# 1. build dependencies (Debian packages)
need=()
for p in cmake g++ make libprotobuf-dev protobuf-compiler zlib1g-dev; do
    dpkg -s "$p" >/dev/null 2>&1 || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
    apt-get update
    $NICE apt-get install -y "${need[@]}"
fi

# 2. MUSEN sources
if [ ! -f "$SRC/MUSEN/CMusen/CMusen.cpp" ] && [ ! -f "$SRC/CMusen/CMusen.cpp" ]; then
    [ -n "$SOURCE" ] || { echo "build_musen.sh: give SOURCE (tree or git dir)" >&2; exit 2; }
    rm -rf "$SRC.partial"; mkdir -p "$SRC.partial"
    if [ -f "$SOURCE/MUSEN/CMusen/CMusen.cpp" ]; then
        cp -r "$SOURCE/MUSEN" "$SOURCE/GeneralFunctions" "$SOURCE/Databases" "$SRC.partial/"
        echo "tree $SOURCE" > "$SRC.partial/ORIGIN"
    elif [ -f "$SOURCE/CMusen/CMusen.cpp" ]; then
        cp -r "$SOURCE/CMusen" "$SOURCE/Databases" "$SOURCE/Models" "$SOURCE/Modules" \
            "$SOURCE/Version" "$SRC.partial/"
        echo "tree $SOURCE" > "$SRC.partial/ORIGIN"
    else
        GIT="git --git-dir=$SOURCE"
        $GIT cat-file -e "$COMMIT^{commit}"
        $GIT ls-tree -r "$COMMIT" -- MUSEN GeneralFunctions Databases CMusen Models Modules Version |
        while read -r mode type sha path; do
            [ "$type" = blob ] || continue
            mkdir -p "$SRC.partial/$(dirname "$path")"
            $GIT cat-file blob "$sha" > "$SRC.partial/$path" 2>/dev/null ||
                { echo "skipped (blob not in this copy): $path"; rm -f "$SRC.partial/$path"; }
        done
        echo "git $($GIT rev-parse "$COMMIT^{commit}")" > "$SRC.partial/ORIGIN"
    fi
    mv "$SRC.partial" "$SRC"
fi
ORIGIN=$(cat "$SRC/ORIGIN")
# the two layouts: 1.70 (MUSEN/, GeneralFunctions/) and 1.71 on (CMusen/, Models/, Modules/)
if [ -f "$SRC/CMusen/CMusen.cpp" ]; then
    VERSION_DIR=$SRC/Version; MAIN=$SRC/CMusen/CMusen.cpp
    STORAGE=$SRC/Modules/SimResultsStorage
else
    VERSION_DIR=$SRC/MUSEN/BuildVersion; MAIN=$SRC/MUSEN/CMusen/CMusen.cpp
    STORAGE=$SRC/GeneralFunctions/SimResultsStorage
fi
printf '#pragma once\nconst std::string _BUILD_HASH = "%s";\n' "${ORIGIN##* }" | cut -c1-200 \
    > "$VERSION_DIR/BuildHash.h.new"
cmp -s "$VERSION_DIR/BuildHash.h.new" "$VERSION_DIR/BuildHash.h" 2>/dev/null &&
    rm "$VERSION_DIR/BuildHash.h.new" ||
    mv "$VERSION_DIR/BuildHash.h.new" "$VERSION_DIR/BuildHash.h"
[ -f "$VERSION_DIR/BuildTime.h" ] ||
    printf '#pragma once\nconst std::string _BUILD_TIME = "%s";\n' "$(date +%y%m%d.%H%M%S)" \
        > "$VERSION_DIR/BuildTime.h"

# 3. CUDA runtime headers and static runtime (PyPI wheels, no toolkit: the runtime wheel
#    has cuda_runtime.h and libcudart_static.a, the nvcc wheel the crt/ headers they
#    include, the cccl wheel thrust/, which two GPU headers include for member pointers;
#    thrust is pointed at its C++ host backend so that g++ can read it)
CUDA=$DEST/cuda-runtime
# (MUSEN 1.71 on also includes curand_kernel.h in a GPU header: the curand wheel has it)
if [ ! -f "$CUDA/nvidia/cuda_runtime/include/cuda_runtime.h" ] || [ ! -f "$CUDA/nvidia/cuda_nvcc/include/crt/host_defines.h" ] ||
   [ ! -f "$CUDA/nvidia/cuda_cccl/include/thrust/device_vector.h" ] ||
   [ ! -f "$CUDA/nvidia/curand/include/curand_kernel.h" ]; then
    $NICE python3 -m pip install --quiet --no-deps --upgrade --target "$CUDA" \
        "nvidia-cuda-runtime-cu12==12.9.79" "nvidia-cuda-nvcc-cu12==12.9.86" "nvidia-cuda-cccl-cu12==12.9.27" \
        "nvidia-curand-cu12==10.3.10.19"
fi
CUDA_INC="$CUDA/nvidia/cuda_runtime/include;$CUDA/nvidia/cuda_nvcc/include;$CUDA/nvidia/cuda_cccl/include;$CUDA/nvidia/curand/include"
CUDA_LIB=$CUDA/nvidia/cuda_runtime/lib

# 4. protobuf sources (as MUSEN's CMake target "protobuf" does)
GEN=$DEST/generated/GeneratedFiles     # MUSEN 1.70 includes "GeneratedFiles/X.pb.h", later ones "X.pb.h"
mkdir -p "$GEN"
if [ ! -f "$GEN/SimulationDescription.pb.cc" ]; then
    protoc --proto_path="$STORAGE" --proto_path="$SRC/Databases/MaterialsDatabase" \
        --cpp_out="$GEN" "$STORAGE/SimulationDescription.proto"
    protoc --proto_path="$SRC/Databases/AgglomerateDatabase" --cpp_out="$GEN" "$SRC/Databases/AgglomerateDatabase/AgglomeratesDatabase.proto"
    protoc --proto_path="$SRC/Databases/GeometriesDatabase" --cpp_out="$GEN" "$SRC/Databases/GeometriesDatabase/GeometriesDatabase.proto"
    protoc --proto_path="$SRC/Databases/MaterialsDatabase" --cpp_out="$GEN" "$SRC/Databases/MaterialsDatabase/MaterialsDatabase.proto"
fi

# 5. a CPU-only CMake project over MUSEN's sources
PROJ=$DEST/project
mkdir -p "$PROJ"
[ -f "$PROJ/gpu_stubs.S" ] || printf '/* generated by build_musen.sh */\n' > "$PROJ/gpu_stubs.S"
cat > "$PROJ/gpu_stub_abort.cpp" <<'EOF'
// generated by build_musen.sh: the target of every stub of a GPU-only symbol
#include <cstdio>
#include <cstdlib>
extern "C" void musen_cpu_build_gpu_stub() {
    std::fprintf(stderr, "cmusen (CPU-only build): a GPU function was called; use SIMULATOR_TYPE CPU\n");
    std::abort();
}
EOF
# GPUSimulator.cuh uses thrust::host_vector without including it (nvcc got it through
# device_vector): force-include thrust/host_vector.h into the sources that reach that header
reach="GPUSimulator.cuh"
for _ in 1 2 3 4 5 6; do
    more=$(grep -rlE "#include *\"($(echo "$reach" | tr ' ' '|' | sed 's/\./\\./g'))\"" "$SRC" --include=*.h --include=*.cuh |
           xargs -r -n1 basename | sort -u | tr '\n' ' ')
    reach=$(echo "$reach $more" | tr ' ' '\n' | grep -v '^$' | sort -u | tr '\n' ' ' | sed 's/ $//')
done
THRUST_USERS=$(grep -rlE "#include *\"($(echo "$reach" | tr ' ' '|' | sed 's/\./\\./g'))\"" "$SRC" --include=*.cpp |
               grep -vE "/(QT_GUI|QTDialogs|MMusen|MusenGUI|Templates)/" | sort | tr '\n' ' ')
cat > "$PROJ/CMakeLists.txt.new" <<EOF
cmake_minimum_required(VERSION 3.18)
project(cmusen_cpu C CXX ASM)
set(CMAKE_CXX_STANDARD 17)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
set(CMAKE_CXX_EXTENSIONS OFF)
set(CMAKE_POSITION_INDEPENDENT_CODE ON)
set(CMAKE_BUILD_TYPE "")
set(CMAKE_CXX_FLAGS "\${CMAKE_CXX_FLAGS} -O3 -pthread -fPIC -w")
set(MUSEN_SRC "$SRC")
file(GLOB_RECURSE headers RELATIVE \${MUSEN_SRC} \${MUSEN_SRC}/*.h)
set(dirs "")
foreach(h \${headers})
  get_filename_component(d \${h} PATH)
  list(APPEND dirs \${MUSEN_SRC}/\${d})
endforeach()
list(REMOVE_DUPLICATES dirs)
file(GLOB_RECURSE sources \${MUSEN_SRC}/*.cpp \${MUSEN_SRC}/*.cc)
list(FILTER sources EXCLUDE REGEX "/(QT_GUI|QTDialogs|MMusen|MusenGUI|Templates)/")
list(FILTER sources EXCLUDE REGEX "/CMusen/CMusen.cpp\$")
file(GLOB generated "$GEN/*.pb.cc")
add_definitions(-D_CRT_SECURE_NO_WARNINGS -D_SCL_SECURE_NO_WARNINGS -DREMOVE_OBSOLETE -D_FILE_OFFSET_BITS=64 -DPATH_CONFIGURED -DTHRUST_DEVICE_SYSTEM=THRUST_DEVICE_SYSTEM_CPP)
include_directories(\${dirs} "$GEN" "$DEST/generated" "$CUDA_INC")
add_library(musencore STATIC \${sources} \${generated})
set_source_files_properties($THRUST_USERS PROPERTIES COMPILE_OPTIONS "-include;thrust/host_vector.h")
add_executable(cmusen "$MAIN" gpu_stub_abort.cpp gpu_stubs.S)
target_link_options(cmusen PRIVATE -Wl,--no-demangle)
target_link_libraries(cmusen musencore protobuf z "$CUDA_LIB/libcudart_static.a" dl rt pthread)
EOF
cmp -s "$PROJ/CMakeLists.txt.new" "$PROJ/CMakeLists.txt" 2>/dev/null && rm "$PROJ/CMakeLists.txt.new" ||
    mv "$PROJ/CMakeLists.txt.new" "$PROJ/CMakeLists.txt"

BUILD=$DEST/build
[ -f "$BUILD/CMakeCache.txt" ] || $NICE cmake -S "$PROJ" -B "$BUILD" >/dev/null
$NICE cmake --build "$BUILD" --target musencore -j "$JOBS"

# 6. link; stub the symbols that only the left-out .cu files define, link again
for attempt in 1 2 3; do
    if $NICE cmake --build "$BUILD" --target cmusen -j "$JOBS" > "$BUILD/link.log" 2>&1; then
        break
    fi
    grep -o "undefined reference to \`[^']*'" "$BUILD/link.log" | sed "s/undefined reference to \`//; s/'\$//" |
        sort -u > "$BUILD/undefined.txt" || true
    if [ ! -s "$BUILD/undefined.txt" ] || [ "$attempt" = 3 ]; then
        cat "$BUILD/link.log" >&2; exit 1
    fi
    {
        cat "$PROJ/gpu_stubs.S"
        while read -r sym; do
            grep -qF ".globl $sym" "$PROJ/gpu_stubs.S" && continue
            printf '\t.text\n\t.globl %s\n\t.type %s, @function\n%s:\n\tjmp musen_cpu_build_gpu_stub\n' "$sym" "$sym" "$sym"
        done < "$BUILD/undefined.txt"
    } > "$PROJ/gpu_stubs.S.new"
    mv "$PROJ/gpu_stubs.S.new" "$PROJ/gpu_stubs.S"
    echo "stubbed $(grep -c '^\s*\.globl' "$PROJ/gpu_stubs.S") GPU-only symbols"
done
cp "$BUILD/cmusen" "$DEST/cmusen"
"$DEST/cmusen" -v
echo "built $DEST/cmusen"
