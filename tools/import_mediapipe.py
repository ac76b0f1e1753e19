#!/usr/bin/env python3
"""Import MediaPipe's person models (TFLite) into ONNX for the station's `person` module.

Usage:
    python3 -m pip download --no-deps mediapipe==0.10.14 -d DIR
    python3 tools/import_mediapipe.py DIR/mediapipe-0.10.14-*.whl [--out models] \
        [--reference tests/data/person_crop.ppm --reference-out tests/data/person_reference.json]

With --reference it also writes TFLite's outputs on that committed network input, which
`tests/suite/person_models.rs` compares with the Rust (tract-onnx) inference.

Needs PyPI `tflite` (the flatbuffer reader), `onnx` and `numpy`; checks the result
against the TFLite runtime (`ai-edge-litert` or `tflite-runtime`) when one is installed,
by running the imported ONNX graph with the script's own numpy interpreter on a test
image and comparing its outputs with TFLite's reference kernels.

The converter turns the whole graph to NCHW: the NHWC input [1,256,256,3] is transposed
once at the start, 4-D activations live in NCHW, and every graph output is given back in
the TFLite model's own shape and layout (so outputs and inputs match the .tflite file).
fp16 weights behind DEQUANTIZE become fp32 initialisers; MediaPipe's custom
`Convolution2DTransposeBias` becomes an ONNX `ConvTranspose` with its bias.
"""

import argparse
import hashlib
import os
import struct
import sys
import zipfile

import numpy as np

try:
    import onnx
    from onnx import TensorProto, helper, numpy_helper
    import tflite
except ImportError as e:  # pragma: no cover - a plain message beats a traceback
    sys.exit(f"import_mediapipe: missing Python package ({e}); "
             "install with: python3 -m pip install tflite onnx numpy")

MODELS = {
    "selfie_segmentation": "mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite",
    "pose_landmark_full": "mediapipe/modules/pose_landmark/pose_landmark_full.tflite",
}

OPSET = 13

BUILTIN_NAMES = {v: k for k, v in tflite.BuiltinOperator.__dict__.items() if not k.startswith("_")}

TFLITE_DTYPES = {
    tflite.TensorType.FLOAT32: np.float32,
    tflite.TensorType.FLOAT16: np.float16,
    tflite.TensorType.INT32: np.int32,
    tflite.TensorType.INT64: np.int64,
}


def sha256_bytes(data):
    return hashlib.sha256(data).hexdigest()


def sha256_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


class Converter:
    """One TFLite subgraph to one ONNX graph (NCHW inside)."""

    def __init__(self, buf, name):
        self.model = tflite.Model.GetRootAsModel(buf, 0)
        if self.model.SubgraphsLength() != 1:
            raise ValueError(f"{name}: expected one subgraph, found {self.model.SubgraphsLength()}")
        self.g = self.model.Subgraphs(0)
        self.name = name
        self.nodes = []
        self.inits = []
        # tensor index -> numpy constant (weights, after DEQUANTIZE)
        self.consts = {}
        # tensor index -> ONNX value name; 4-D activations are NCHW under that name
        self.names = {}
        # numpy reference: the same graph run op by op in NHWC with plain numpy
        self.counter = 0

    # --- tensors -------------------------------------------------------------
    def tensor(self, i):
        return self.g.Tensors(i)

    def shape(self, i):
        return [int(d) for d in self.tensor(i).ShapeAsNumpy()]

    def const_of(self, i):
        """The constant data of tensor i, or None when it is an activation."""
        if i in self.consts:
            return self.consts[i]
        t = self.tensor(i)
        b = self.model.Buffers(t.Buffer())
        if b is None or b.DataLength() == 0:
            return None
        dtype = TFLITE_DTYPES.get(t.Type())
        if dtype is None:
            raise ValueError(f"{self.name}: tensor {t.Name()} has unsupported type {t.Type()}")
        raw = b.DataAsNumpy().tobytes()
        arr = np.frombuffer(raw, dtype=dtype).reshape(self.shape(i)).copy()
        self.consts[i] = arr
        return arr

    def fresh(self, base):
        self.counter += 1
        return f"{base}_{self.counter}"

    def init(self, base, arr):
        name = self.fresh(base)
        self.inits.append(numpy_helper.from_array(np.ascontiguousarray(arr), name))
        return name

    def value(self, i):
        """The ONNX name holding activation tensor i (NCHW when 4-D)."""
        if i in self.names:
            return self.names[i]
        c = self.const_of(i)
        if c is None:
            raise ValueError(f"{self.name}: tensor {self.tensor(i).Name()} used before it is made")
        c = c.astype(np.float32) if c.dtype == np.float16 else c
        if c.ndim == 4:
            c = c.transpose(0, 3, 1, 2)
        elif c.ndim in (1, 2, 3) and c.dtype == np.float32:
            # A per-channel constant broadcast against an NCHW activation.
            flat = c.reshape(-1)
            c = flat.reshape(1, -1, 1, 1) if flat.size > 1 else flat.reshape(())
        name = self.init("const", c)
        self.names[i] = name
        return name

    def node(self, op, inputs, outputs, **attrs):
        self.nodes.append(helper.make_node(op, inputs, outputs, name=self.fresh(op), **attrs))

    def activation(self, x, fused, out):
        """Apply TFLite's fused activation to value x, writing out."""
        A = tflite.ActivationFunctionType
        if fused == A.NONE:
            self.node("Identity", [x], [out])
        elif fused == A.RELU:
            self.node("Relu", [x], [out])
        elif fused == A.RELU6:
            self.node("Clip", [x, self.init("lo", np.array(0, np.float32)),
                               self.init("hi", np.array(6, np.float32))], [out])
        else:
            raise ValueError(f"{self.name}: fused activation {fused} not handled")

    def out_name(self, i):
        name = self.fresh("t")
        self.names[i] = name
        return name

    # --- padding -------------------------------------------------------------
    @staticmethod
    def same_pads(size, k, s, d):
        eff = (k - 1) * d + 1
        out = -(-size // s)
        total = max((out - 1) * s + eff - size, 0)
        return total // 2, total - total // 2

    def conv_pads(self, in_shape, kh, kw, sh, sw, dh, dw, padding):
        if padding == tflite.Padding.VALID:
            return [0, 0, 0, 0]
        t, b = self.same_pads(in_shape[1], kh, sh, dh)
        l, r = self.same_pads(in_shape[2], kw, sw, dw)
        return [t, l, b, r]

    # --- ops -----------------------------------------------------------------
    def convert(self):
        g = self.g
        if g.InputsLength() != 1:
            raise ValueError(f"{self.name}: expected one input")
        inp = g.Inputs(0)
        in_shape = self.shape(inp)
        graph_in = helper.make_tensor_value_info("input", TensorProto.FLOAT, in_shape)
        self.node("Transpose", ["input"], ["input_nchw"], perm=[0, 3, 1, 2])
        self.names[inp] = "input_nchw"

        for k in range(g.OperatorsLength()):
            op = g.Operators(k)
            oc = self.model.OperatorCodes(op.OpcodeIndex())
            code = max(oc.BuiltinCode(), oc.DeprecatedBuiltinCode())
            ins = [int(i) for i in op.InputsAsNumpy()]
            outs = [int(i) for i in op.OutputsAsNumpy()]
            handler = BUILTIN_NAMES.get(code, str(code))
            if code == tflite.BuiltinOperator.CUSTOM:
                handler = "CUSTOM_" + oc.CustomCode().decode()
            fn = getattr(self, "op_" + handler, None)
            if fn is None:
                raise ValueError(f"{self.name}: operator {handler} is not handled by this importer")
            fn(op, ins, outs)

        outputs = []
        for j in range(g.OutputsLength()):
            i = g.Outputs(j)
            shp = self.shape(i)
            name = f"output_{j}"
            src = self.names[i]
            if len(shp) == 4:
                self.node("Transpose", [src], [name], perm=[0, 2, 3, 1])
            else:
                self.node("Identity", [src], [name])
            outputs.append(helper.make_tensor_value_info(name, TensorProto.FLOAT, shp))

        graph = helper.make_graph(self.nodes, self.name, [graph_in], outputs, self.inits)
        model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)],
                                  producer_name="fitstation tools/import_mediapipe.py")
        model.ir_version = 8
        onnx.checker.check_model(model)
        return model

    def op_DEQUANTIZE(self, op, ins, outs):
        c = self.const_of(ins[0])
        if c is None or c.dtype != np.float16:
            raise ValueError(f"{self.name}: DEQUANTIZE of something other than fp16 weights")
        self.consts[outs[0]] = c.astype(np.float32)

    def _conv(self, op, ins, outs, depthwise):
        if depthwise:
            o = tflite.DepthwiseConv2DOptions()
        else:
            o = tflite.Conv2DOptions()
        t = op.BuiltinOptions()
        o.Init(t.Bytes, t.Pos)
        w = self.const_of(ins[1])
        if w is None:
            raise ValueError(f"{self.name}: convolution with non-constant weights")
        w = w.astype(np.float32)
        in_shape = self.shape(ins[0])
        if depthwise:
            # [1, KH, KW, C*M] -> [C*M, 1, KH, KW], one group per input channel
            kh, kw = w.shape[1], w.shape[2]
            wt = w.transpose(3, 0, 1, 2)
            group = in_shape[3]
        else:
            # [O, KH, KW, I] -> [O, I, KH, KW]
            kh, kw = w.shape[1], w.shape[2]
            wt = w.transpose(0, 3, 1, 2)
            group = 1
        sh, sw = o.StrideH(), o.StrideW()
        dh, dw = o.DilationHFactor(), o.DilationWFactor()
        pads = self.conv_pads(in_shape, kh, kw, sh, sw, dh, dw, o.Padding())
        inputs = [self.value(ins[0]), self.init("w", wt)]
        if len(ins) > 2 and ins[2] >= 0:
            b = self.const_of(ins[2])
            inputs.append(self.init("b", b.astype(np.float32).reshape(-1)))
        tmp = self.fresh("conv")
        self.node("Conv", inputs, [tmp], kernel_shape=[kh, kw], strides=[sh, sw],
                  dilations=[dh, dw], pads=pads, group=group)
        self.activation(tmp, o.FusedActivationFunction(), self.out_name(outs[0]))

    def op_CONV_2D(self, op, ins, outs):
        self._conv(op, ins, outs, depthwise=False)

    def op_DEPTHWISE_CONV_2D(self, op, ins, outs):
        self._conv(op, ins, outs, depthwise=True)

    def _pool(self, op, ins, outs, kind):
        o = tflite.Pool2DOptions()
        t = op.BuiltinOptions()
        o.Init(t.Bytes, t.Pos)
        in_shape = self.shape(ins[0])
        kh, kw = o.FilterHeight(), o.FilterWidth()
        sh, sw = o.StrideH(), o.StrideW()
        pads = self.conv_pads(in_shape, kh, kw, sh, sw, 1, 1, o.Padding())
        tmp = self.fresh("pool")
        attrs = dict(kernel_shape=[kh, kw], strides=[sh, sw], pads=pads)
        if kind == "AveragePool":
            attrs["count_include_pad"] = 0  # TFLite averages over the valid cells only
        self.node(kind, [self.value(ins[0])], [tmp], **attrs)
        self.activation(tmp, o.FusedActivationFunction(), self.out_name(outs[0]))

    def op_AVERAGE_POOL_2D(self, op, ins, outs):
        self._pool(op, ins, outs, "AveragePool")

    def op_MAX_POOL_2D(self, op, ins, outs):
        self._pool(op, ins, outs, "MaxPool")

    def _binary(self, op, ins, outs, kind, opts_cls):
        o = opts_cls()
        t = op.BuiltinOptions()
        fused = tflite.ActivationFunctionType.NONE
        if t is not None:
            o.Init(t.Bytes, t.Pos)
            fused = o.FusedActivationFunction()
        tmp = self.fresh(kind.lower())
        self.node(kind, [self.value(ins[0]), self.value(ins[1])], [tmp])
        self.activation(tmp, fused, self.out_name(outs[0]))

    def op_ADD(self, op, ins, outs):
        self._binary(op, ins, outs, "Add", tflite.AddOptions)

    def op_MUL(self, op, ins, outs):
        self._binary(op, ins, outs, "Mul", tflite.MulOptions)

    def op_RELU(self, op, ins, outs):
        self.node("Relu", [self.value(ins[0])], [self.out_name(outs[0])])

    def op_LOGISTIC(self, op, ins, outs):
        self.node("Sigmoid", [self.value(ins[0])], [self.out_name(outs[0])])

    def op_HARD_SWISH(self, op, ins, outs):
        # x * relu6(x + 3) / 6, written as x * HardSigmoid(x; 1/6, 0.5)
        x = self.value(ins[0])
        hs = self.fresh("hsig")
        self.node("HardSigmoid", [x], [hs], alpha=1.0 / 6.0, beta=0.5)
        self.node("Mul", [x, hs], [self.out_name(outs[0])])

    def op_PAD(self, op, ins, outs):
        p = self.const_of(ins[1])
        if p is None or p.shape != (4, 2):
            raise ValueError(f"{self.name}: PAD with non-constant or non-4-D paddings")
        nchw = p[[0, 3, 1, 2]]
        pads = np.concatenate([nchw[:, 0], nchw[:, 1]]).astype(np.int64)
        self.node("Pad", [self.value(ins[0]), self.init("pads", pads)],
                  [self.out_name(outs[0])], mode="constant")

    def op_RESIZE_BILINEAR(self, op, ins, outs):
        o = tflite.ResizeBilinearOptions()
        t = op.BuiltinOptions()
        o.Init(t.Bytes, t.Pos)
        in_shape = self.shape(ins[0])
        out_shape = self.shape(outs[0])
        if o.AlignCorners():
            mode = "align_corners"
        elif o.HalfPixelCenters():
            mode = "half_pixel"
        else:
            mode = "asymmetric"
        scales = np.array([1.0, 1.0, out_shape[1] / in_shape[1], out_shape[2] / in_shape[2]],
                          np.float32)
        self.node("Resize", [self.value(ins[0]), self.init("roi", np.zeros(0, np.float32)),
                             self.init("scales", scales)], [self.out_name(outs[0])],
                  mode="linear", coordinate_transformation_mode=mode)

    def op_RESHAPE(self, op, ins, outs):
        x = self.value(ins[0])
        if len(self.shape(ins[0])) == 4:
            nhwc = self.fresh("nhwc")
            self.node("Transpose", [x], [nhwc], perm=[0, 2, 3, 1])
            x = nhwc
        out_shape = self.shape(outs[0])
        if len(out_shape) == 4:
            raise ValueError(f"{self.name}: RESHAPE to 4-D not handled")
        self.node("Reshape", [x, self.init("shape", np.array(out_shape, np.int64))],
                  [self.out_name(outs[0])])

    def op_CUSTOM_Convolution2DTransposeBias(self, op, ins, outs):
        # custom options: TfLiteTransposeConvParams {padding, stride_width, stride_height}
        raw = op.CustomOptionsAsNumpy().tobytes()
        padding, sw, sh = struct.unpack("<iii", raw[:12])
        w = self.const_of(ins[1]).astype(np.float32)  # [O, KH, KW, I]
        b = self.const_of(ins[2]).astype(np.float32).reshape(-1)
        kh, kw = w.shape[1], w.shape[2]
        in_shape, out_shape = self.shape(ins[0]), self.shape(outs[0])
        if padding == 1:  # SAME: output = input * stride, the overhang trimmed as TFLite does
            th = max(kh - sh, 0)
            tw = max(kw - sw, 0)
            pads = [th // 2, tw // 2, th - th // 2, tw - tw // 2]
        elif padding == 2:  # VALID
            pads = [0, 0, 0, 0]
        else:
            raise ValueError(f"{self.name}: transpose convolution padding {padding} unknown")
        expect = [(in_shape[1] - 1) * sh + kh - pads[0] - pads[2],
                  (in_shape[2] - 1) * sw + kw - pads[1] - pads[3]]
        if expect != out_shape[1:3]:
            raise ValueError(f"{self.name}: transpose convolution shape {expect} != {out_shape}")
        self.node("ConvTranspose",
                  [self.value(ins[0]), self.init("w", w.transpose(3, 0, 1, 2)), self.init("b", b)],
                  [self.out_name(outs[0])], kernel_shape=[kh, kw], strides=[sh, sw], pads=pads)


def numpy_reference(model, x):
    """Run the ONNX graph with a small numpy interpreter (the fallback check)."""
    vals = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
    vals["input"] = x
    for n in model.graph.node:
        a = {at.name: helper.get_attribute_value(at) for at in n.attribute}
        ii = [vals[i] for i in n.input]
        if n.op_type == "Transpose":
            r = ii[0].transpose(a["perm"])
        elif n.op_type == "Identity":
            r = ii[0]
        elif n.op_type == "Relu":
            r = np.maximum(ii[0], 0)
        elif n.op_type == "Clip":
            r = np.clip(ii[0], ii[1], ii[2])
        elif n.op_type == "Sigmoid":
            with np.errstate(over="ignore"):
                r = 1 / (1 + np.exp(-ii[0]))
        elif n.op_type == "HardSigmoid":
            r = np.clip(ii[0] * a["alpha"] + a["beta"], 0, 1)
        elif n.op_type == "Add":
            r = ii[0] + ii[1]
        elif n.op_type == "Mul":
            r = ii[0] * ii[1]
        elif n.op_type == "Reshape":
            r = ii[0].reshape(ii[1])
        elif n.op_type == "Pad":
            p = ii[1]
            r = np.pad(ii[0], list(zip(p[:4], p[4:])))
        elif n.op_type in ("Conv", "ConvTranspose", "AveragePool", "MaxPool", "Resize"):
            r = _np_spatial(n.op_type, a, ii)
        else:
            raise ValueError(f"numpy reference: {n.op_type} not handled")
        vals[n.output[0]] = r.astype(np.float32)
    return [vals[o.name] for o in model.graph.output]


def _np_spatial(kind, a, ii):
    x = ii[0]
    if kind == "Resize":
        n, c, h, w = x.shape
        oh, ow = int(round(h * ii[2][2])), int(round(w * ii[2][3]))
        mode = a["coordinate_transformation_mode"].decode()

        def src(o, i, out):
            o = np.arange(out, dtype=np.float64)
            if mode == "align_corners":
                s = o * (i - 1) / max(out - 1, 1)
            elif mode == "half_pixel":
                s = (o + 0.5) * i / out - 0.5
            else:
                s = o * i / out
            s = np.clip(s, 0, i - 1)
            lo = np.floor(s).astype(int)
            hi = np.minimum(lo + 1, i - 1)
            return lo, hi, (s - lo).astype(np.float32)

        yl, yh, fy = src(None, h, oh)
        xl, xh, fx = src(None, w, ow)
        top = x[:, :, yl][..., xl] * (1 - fx) + x[:, :, yl][..., xh] * fx
        bot = x[:, :, yh][..., xl] * (1 - fx) + x[:, :, yh][..., xh] * fx
        return top * (1 - fy)[:, None] + bot * fy[:, None]
    kh, kw = a["kernel_shape"]
    sh, sw = a.get("strides", [1, 1])
    t, l, b, r = a.get("pads", [0, 0, 0, 0])
    if kind == "ConvTranspose":
        w, bias = ii[1], ii[2]  # [I, O, KH, KW]
        n, c, h, wd = x.shape
        full = np.zeros((n, w.shape[1], (h - 1) * sh + kh, (wd - 1) * sw + kw), np.float32)
        for dy in range(kh):
            for dx in range(kw):
                contrib = np.einsum("nchw,co->nohw", x, w[:, :, dy, dx])
                full[:, :, dy:dy + (h - 1) * sh + 1:sh, dx:dx + (wd - 1) * sw + 1:sw] += contrib
        out = full[:, :, t:full.shape[2] - b, l:full.shape[3] - r]
        return out + bias.reshape(1, -1, 1, 1)
    dh, dw = a.get("dilations", [1, 1])
    pad_val = -np.inf if kind == "MaxPool" else 0.0
    xp = np.pad(x, ((0, 0), (0, 0), (t, b), (l, r)), constant_values=pad_val)
    n, c, hp, wp = xp.shape
    oh = (hp - ((kh - 1) * dh + 1)) // sh + 1
    ow = (wp - ((kw - 1) * dw + 1)) // sw + 1
    # windows: [n, c, kh, kw, oh, ow]
    win = np.empty((n, c, kh, kw, oh, ow), np.float32)
    for dy in range(kh):
        for dx in range(kw):
            win[:, :, dy, dx] = xp[:, :, dy * dh:dy * dh + (oh - 1) * sh + 1:sh,
                                   dx * dw:dx * dw + (ow - 1) * sw + 1:sw]
    if kind == "MaxPool":
        return win.max(axis=(2, 3))
    if kind == "AveragePool":
        ones = np.pad(np.ones((1, 1, x.shape[2], x.shape[3]), np.float32), ((0, 0), (0, 0), (t, b), (l, r)))
        cnt = np.empty((1, 1, kh, kw, oh, ow), np.float32)
        for dy in range(kh):
            for dx in range(kw):
                cnt[:, :, dy, dx] = ones[:, :, dy:dy + (oh - 1) * sh + 1:sh, dx:dx + (ow - 1) * sw + 1:sw]
        return win.sum(axis=(2, 3)) / cnt.sum(axis=(2, 3))
    wt = ii[1]
    group = a.get("group", 1)
    o = wt.shape[0]
    cg = c // group
    og = o // group
    out = np.empty((n, o, oh, ow), np.float32)
    for gi in range(group):
        xs = win[:, gi * cg:(gi + 1) * cg]
        ws = wt[gi * og:(gi + 1) * og]
        out[:, gi * og:(gi + 1) * og] = np.einsum("ncyxhw,ocyx->nohw", xs, ws)
    if len(ii) > 2:
        out += ii[2].reshape(1, -1, 1, 1)
    return out


def tflite_runtime_outputs(tfl_bytes, x, reference_kernels):
    """The TFLite runtime's outputs in the model's output order, or None if none is installed.

    reference_kernels: TFLite's reference kernels (BUILTIN_REF) instead of the default
    optimised ones (XNNPACK); the two differ between themselves by more than the import
    does (pose landmarks: 0.18 px), so the check is made against the reference kernels."""
    try:
        from ai_edge_litert.interpreter import Interpreter, OpResolverType
    except ImportError:
        try:
            from tflite_runtime.interpreter import Interpreter, OpResolverType
        except ImportError:
            return None
    rt = OpResolverType.BUILTIN_REF if reference_kernels else OpResolverType.AUTO
    it = Interpreter(model_content=tfl_bytes, experimental_op_resolver_type=rt)
    it.allocate_tensors()
    it.set_tensor(it.get_input_details()[0]["index"], x)
    it.invoke()
    # get_output_details() follows the subgraph's output order
    return [it.get_tensor(d["index"]).copy() for d in it.get_output_details()]


def test_input(shape):
    """A deterministic smooth test image in [0,1] (NHWC): gradients plus a bright blob."""
    n, h, w, c = shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.empty(shape, np.float32)
    for ch in range(c):
        img[0, :, :, ch] = 0.5 + 0.25 * np.sin(xx / (11 + 3 * ch)) * np.cos(yy / (17 + ch))
    blob = np.exp(-(((xx - w / 2) / (w / 6)) ** 2 + ((yy - h / 2) / (h / 3)) ** 2))
    img[0] = np.clip(img[0] * (1 - blob[..., None]) + 0.9 * blob[..., None], 0, 1)
    return img


def read_ppm(path):
    """An 8-bit binary PPM (P6) as an [1, H, W, 3] float array in [0, 1]."""
    with open(path, "rb") as f:
        data = f.read()
    fields = []
    pos = 0
    while len(fields) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        fields.append(data[pos:end])
        pos = end
    if fields[0] != b"P6" or fields[3] != b"255":
        raise ValueError(f"{path}: not an 8-bit binary PPM")
    w, h = int(fields[1]), int(fields[2])
    pix = np.frombuffer(data[pos + 1:pos + 1 + w * h * 3], np.uint8)
    if pix.size != w * h * 3:
        raise ValueError(f"{path}: truncated")
    return pix.reshape(1, h, w, 3).astype(np.float32) / 255.0


# Every 8th cell of a 256x256 map, from cell 4: a 32x32 sample for the reference file.
SUBSAMPLE = (slice(4, None, 8), slice(4, None, 8))


def reference_outputs(wheel, image_path):
    """TFLite's outputs on a committed network input, for the Rust cross-check test."""
    x = read_ppm(image_path)
    if x.shape != (1, 256, 256, 3):
        raise ValueError(f"{image_path}: expected a 256x256 image, found {x.shape}")
    out = {"image": os.path.basename(image_path), "image_sha256": sha256_file(image_path),
           "subsample": "cells [4::8, 4::8] of the 256x256 map, row-major"}
    with zipfile.ZipFile(wheel) as z:
        for name, member in MODELS.items():
            tfl = z.read(member)
            try:
                r = tflite_runtime_outputs(tfl, x, reference_kernels=True)
                runtime = "TFLite reference kernels"
            except RuntimeError:
                r = tflite_runtime_outputs(tfl, x, reference_kernels=False)
                runtime = "TFLite XNNPACK"
            if r is None:
                sys.exit("import_mediapipe: --reference needs a TFLite runtime (pip install ai-edge-litert)")
            ours = numpy_reference(Converter(tfl, name).convert(), x)
            diffs = [float(np.max(np.abs(a.reshape(b.shape) - b))) for a, b in zip(r, ours)]
            print(f"reference {name} ({runtime}): max |numpy(onnx) - TFLite| per output {diffs}")
            if name == "selfie_segmentation":
                out[name] = {"runtime": runtime,
                             "prob": r[0][0, :, :, 0][SUBSAMPLE].ravel().tolist()}
            else:
                with np.errstate(over="ignore"):
                    mask = 1.0 / (1.0 + np.exp(-r[2][0, :, :, 0].astype(np.float64)))
                out[name] = {"runtime": runtime,
                             "landmarks": r[0].ravel().tolist(),
                             "presence": float(r[1].ravel()[0]),
                             "mask_prob": mask[SUBSAMPLE].ravel().tolist(),
                             "world_landmarks": r[4].ravel().tolist()}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("wheel", help="the mediapipe-0.10.14 wheel (python3 -m pip download --no-deps mediapipe==0.10.14)")
    ap.add_argument("--out", default="models", help="output folder (default: models)")
    ap.add_argument("--tol", type=float, default=1e-3,
                    help="largest allowed output difference against TFLite's reference kernels, "
                         "relative to max(1, max |output|) (default 1e-3)")
    ap.add_argument("--reference", metavar="PPM",
                    help="a 256x256 network input (tests/data/person_crop.ppm): write TFLite's "
                         "outputs on it to --reference-out for the Rust cross-check test")
    ap.add_argument("--reference-out", metavar="JSON", default="tests/data/person_reference.json")
    args = ap.parse_args()

    if not os.path.isfile(args.wheel):
        sys.exit(f"import_mediapipe: no wheel at {args.wheel}")
    os.makedirs(args.out, exist_ok=True)
    report = {"wheel": os.path.basename(args.wheel), "wheel_sha256": sha256_file(args.wheel), "models": []}
    ok = True
    with zipfile.ZipFile(args.wheel) as z:
        for name, member in MODELS.items():
            try:
                tfl = z.read(member)
            except KeyError:
                sys.exit(f"import_mediapipe: {member} is not in {args.wheel}")
            model = Converter(tfl, name).convert()
            path = os.path.join(args.out, name + ".onnx")
            onnx.save(model, path)
            in_shape = [d.dim_value for d in model.graph.input[0].type.tensor_type.shape.dim]
            x = test_input(in_shape)
            ours = numpy_reference(model, x)
            fast = tflite_runtime_outputs(tfl, x, reference_kernels=False)
            ref_name = "TFLite reference kernels"
            try:
                ref = tflite_runtime_outputs(tfl, x, reference_kernels=True)
            except RuntimeError as e:
                # MediaPipe's custom transpose convolution exists only in the XNNPACK delegate.
                print(f"  TFLite reference kernels refuse the model ({str(e).splitlines()[0]}); "
                      "checking against XNNPACK")
                ref, ref_name = fast, "TFLite XNNPACK"
            line = f"{name}: {len(model.graph.node)} ONNX nodes, {os.path.getsize(path)} bytes"
            print(line)
            if ref is None:
                print("  no TFLite runtime installed (pip install ai-edge-litert): "
                      "the import is unchecked")
                ok = False
            for j, o in enumerate(ours):
                msg = f"  output_{j} {list(o.shape)} max|x| {float(np.max(np.abs(o))):.4g}"
                if ref is not None:
                    r = ref[j].reshape(o.shape)
                    d = float(np.max(np.abs(r - o)))
                    rel = d / max(1.0, float(np.max(np.abs(r))))
                    msg += f"  max diff vs {ref_name} {d:.3g} (relative {rel:.2g})"
                    if ref is not fast:
                        dx = float(np.max(np.abs(fast[j].reshape(o.shape) - o)))
                        msg += f", vs TFLite XNNPACK {dx:.3g}"
                    ok = ok and rel <= args.tol
                print(msg)
            report["models"].append((name, member, sha256_bytes(tfl), path, sha256_file(path)))
    print(f"wheel {report['wheel']} sha256 {report['wheel_sha256']}")
    for name, member, tsha, path, osha in report["models"]:
        print(f"{member} sha256 {tsha}")
        print(f"{path} sha256 {osha}")
    if args.reference:
        import json
        ref = reference_outputs(args.wheel, args.reference)
        with open(args.reference_out, "w") as f:
            json.dump(ref, f, indent=None, separators=(",", ":"))
            f.write("\n")
        print(f"wrote {args.reference_out}")
    if not ok:
        sys.exit(f"import_mediapipe: an output differs from the reference by more than {args.tol}")


if __name__ == "__main__":
    main()
