#!/bin/sh
# Installs PyTorch (CPU build) into benches/peers/.venv-torch for benches/peers/tnet_torch.py.
# Never run in CI. From PyPI by default: its Linux wheel pulls ~2.4 GB of CUDA libraries (check
# free disk first: df -h .). Where download.pytorch.org is reachable, TORCH_INDEX=cpu uses the
# much smaller CPU-only wheel index instead.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
python3 -m venv "$here/.venv-torch"
"$here/.venv-torch/bin/pip" install --quiet --upgrade pip
if [ "${TORCH_INDEX:-}" = cpu ]; then
    "$here/.venv-torch/bin/pip" install --quiet torch --index-url https://download.pytorch.org/whl/cpu
else
    "$here/.venv-torch/bin/pip" install --quiet torch
fi
"$here/.venv-torch/bin/python" -c 'import torch; print("torch", torch.__version__)'
echo "run: $here/.venv-torch/bin/python $here/tnet_torch.py"
