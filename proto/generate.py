"""Regenerate proto/*_pb2.py and .pyi from proto/*.proto (touchdown.proto: the log; service.proto:
the live service's checkpoints and telemetry).

    python proto/generate.py            # writes next to the .proto
    python proto/generate.py OUT_DIR    # writes into OUT_DIR (the freshness test uses this)

Uses grpcio-tools' bundled protoc (pinned in pyproject.toml with the protobuf runtime it stamps).
"""
from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def generate(out_dir: Path) -> None:
    from grpc_tools import protoc

    out_dir.mkdir(parents=True, exist_ok=True)
    args = ["protoc", f"-I{HERE}", f"--python_out={out_dir}", f"--pyi_out={out_dir}",
            *(str(p) for p in sorted(HERE.glob("*.proto")))]
    if protoc.main(args) != 0:
        raise SystemExit("protoc failed")


if __name__ == "__main__":
    generate(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE)
