#!/bin/sh
# Installs PyTorch (CPU build) into benches/peers/.venv-torch for benches/peers/tnet_torch.py.
# Never run in CI. The CPU wheel index keeps the download small (PyPI's default Linux wheel pulls
# ~2.4 GB of CUDA libraries). Check free disk first (df -h .).
set -eu
here=$(cd "$(dirname "$0")" && pwd)
python3 -m venv "$here/.venv-torch"
"$here/.venv-torch/bin/pip" install --quiet --upgrade pip
"$here/.venv-torch/bin/pip" install --quiet torch --index-url https://download.pytorch.org/whl/cpu
"$here/.venv-torch/bin/python" -c 'import torch; print("torch", torch.__version__)'
echo "run: $here/.venv-torch/bin/python $here/tnet_torch.py"
