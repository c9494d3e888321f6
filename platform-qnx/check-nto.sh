#!/usr/bin/env bash
# Type-checks skyframe-qnx, with the shell, the core and every dependency under it, for QNX
# Neutrino: `cargo check` needs no linker, so no QNX SDP. The QNX targets are tier 3 (no
# prebuilt std): std is built from source, which needs the nightly toolchain with rust-src.
#
#   platform-qnx/check-nto.sh [TARGET...]
#
# Default targets: x86_64-pc-nto-qnx710 aarch64-unknown-nto-qnx710. x86_64-pc-nto-qnx800 can
# be named but does not pass yet (libc 0.2.191 does not know its target_env "nto80"; see
# platform-qnx/README.md).
set -euo pipefail
cd "$(dirname "$0")/.."

targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(x86_64-pc-nto-qnx710 aarch64-unknown-nto-qnx710)

# A target directory of its own: std built for QNX stays apart from the host builds.
export CARGO_TARGET_DIR="${QNX_CHECK_TARGET_DIR:-${CARGO_TARGET_DIR:-target}/nto-check}"

for target in "${targets[@]}"; do
  echo "== cargo check for $target"
  start=$SECONDS
  cargo +nightly check -Zbuild-std=std,panic_abort --target "$target" -p skyframe-qnx --all-targets
  echo "$target: type-checks ($((SECONDS - start)) s)"
done
