"""Evaluation of the nodes in front of a MaterialX surface input: constants,
textures (``image`` / ``tiledimage`` with colour space, address modes, ``texcoord``,
``place2d`` and ``geompropvalue`` coordinates folded into the st transform),
primvar readers, ``normalmap``, ``constant``, ``dot``, ``convert``, ``extract`` /
``separate3`` and ``multiply`` by a constant (:class:`Mapper`); anything else is
reported for the input it feeds. See :mod:`cmlt.usd.materialx` for the mapping."""
from __future__ import annotations

import math
import os
from typing import List

from .color import to_rendering_space
from .mtlx_graph import Node, Src, UsdNode, as_float, as_tuple

__all__ = ["Const", "Tex", "Prim", "Mapper", "CHANNELS", "scale_rec"]


class Const:
    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value


class Tex:
    """A texture lookup: ``rec`` is the record the bridge loads
    (``cmlt.shot.bridge``: texture, output, wraps, scale, bias, st...)."""

    __slots__ = ("rec",)

    def __init__(self, rec):
        self.rec = rec


class Prim:
    """A primvar read per vertex (geompropvalue / UsdPrimvarReader)."""

    __slots__ = ("varname", "fallback", "node")

    def __init__(self, varname, fallback, node):
        self.varname, self.fallback, self.node = varname, fallback, node


_ADDRESS = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "constant": "black"}
_IDENTITY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)
CHANNELS = "rgba"


class Mapper:
    """Walks one surface shader's graph and collects UsdPreviewSurface inputs."""

    def __init__(self, material: str, warnings: List[str]):
        self.material = material
        self.warnings = warnings
        self._said = set()

    def warn(self, msg: str):
        if msg not in self._said:
            self._said.add(msg)
            self.warnings.append(f"{self.material}: {msg}")

    # -- constants
    def const(self, src: Src, kind: str):
        """A constant as a float ('scalar'), a rendering-space RGB ('colour')
        or a tuple ('vector')."""
        v = src.value
        if kind == "scalar":
            return as_float(v)
        if kind == "colour":
            rgb = as_tuple(v, 3)
            return to_rendering_space(rgb, src.colorspace or "lin_rec709")
        return as_tuple(v, 3) if v is not None else None

    # -- one input, through its nodes
    def eval(self, node: Node, name: str, kind: str, depth: int = 0):
        """Const | Tex | Prim for ``node.name``; an input driven by a node
        without a mapping (warned) takes its node definition's default."""
        src = node.input(name)
        if src.node is None:
            return Const(self.const(src, kind))
        got = self.eval_source(src, node, name, kind, depth)
        if got is None:
            return Const(self.const(Src(name, value=node.default(name)), kind))
        return got

    def eval_source(self, src: Src, owner: Node, name: str, kind: str, depth: int):
        n = src.node
        if depth > 32:
            self.warn(f"{owner.path}: input {name}: node chain too deep; using its default")
            return None
        cat = n.category
        if cat in ("image", "tiledimage", "UsdUVTexture"):
            return self.image(n, src.output, kind)
        if cat in ("constant",):
            return self.eval(n, "value", kind, depth + 1)
        if cat in ("dot", "convert"):
            return self.eval(n, "in", kind, depth + 1)
        if cat in ("geompropvalue", "geompropvalueuniform"):
            gp = n.input("geomprop").value
            return Prim(str(gp or ""), n.input("default").value, n)
        if cat == "UsdPrimvarReader":
            vn = n.input("varname").value
            return Prim(str(vn or ""), n.input("fallback").value, n)
        if cat in ("extract", "separate3", "separate4"):
            return self.channel(n, src.output, kind, depth)
        if cat == "multiply":
            return self.multiply(n, kind, depth)
        if cat == "normalmap":
            return self.normalmap(n, depth)
        self.warn(f"node {n.path} ({cat}) feeding input {name} of {owner.path} has no "
                  f"mapping in cmlt; {name} uses its value or default")
        return None

    def channel(self, n: Node, output: str, kind: str, depth: int):
        if n.category == "extract":
            idx = int(as_float(n.input("index").value, 0.0))
        else:
            idx = {"outr": 0, "outx": 0, "outg": 1, "outy": 1, "outb": 2, "outz": 2,
                   "outa": 3, "outw": 3}.get(output, 0)
        inner = self.eval(n, "in", "vector", depth + 1)
        if isinstance(inner, Tex):
            rec = dict(inner.rec)
            rec["output"] = CHANNELS[max(0, min(idx, 3))]
            return Tex(rec)
        if isinstance(inner, Const):
            v = as_tuple(inner.value, 4)
            return Const(v[max(0, min(idx, 3))] if kind == "scalar" else (v[idx],) * 3)
        if inner is not None:
            self.warn(f"node {n.path} ({n.category}) takes a channel of a primvar; not "
                      f"supported, using the default")
        return None

    def multiply(self, n: Node, kind: str, depth: int):
        a = self.eval(n, "in1", kind, depth + 1)
        b = self.eval(n, "in2", "scalar" if n.input("in2").node is None and
                      isinstance(n.input("in2").value, (int, float)) else kind, depth + 1)
        if isinstance(a, Const) and isinstance(b, Tex):
            a, b = b, a
        if isinstance(a, Const) and isinstance(b, Const):
            x, y = a.value, b.value
            if isinstance(x, tuple) or isinstance(y, tuple):
                x3, y3 = as_tuple(x, 3), as_tuple(y, 3)
                return Const(tuple(p * q for p, q in zip(x3, y3)))
            return Const(float(x) * float(y))
        if isinstance(a, Tex) and isinstance(b, Const):
            return Tex(scale_rec(a.rec, b.value))
        self.warn(f"node {n.path} (multiply) multiplies two varying values; only a texture "
                  f"times a constant is folded, using the default")
        return None

    def normalmap(self, n: Node, depth: int):
        inner = self.eval(n, "in", "vector", depth + 1)
        space = n.input("space").value
        if space not in (None, "", "tangent"):
            self.warn(f"node {n.path} (normalmap) space '{space}' is not supported; only "
                      f"tangent-space maps are")
            return None
        if not isinstance(inner, Tex):
            return None
        s = as_float(n.input("scale").value, 1.0) if n.input("scale").value is not None \
            else 1.0
        rec = dict(inner.rec)
        sc, bi = as_tuple(rec.get("scale"), 4, 1.0), as_tuple(rec.get("bias"), 4, 0.0)
        f = (2 * s, 2 * s, 2.0, 1.0)
        g = (-s, -s, -1.0, 0.0)
        rec["scale"] = tuple(sc[k] * f[k] for k in range(4))
        rec["bias"] = tuple(bi[k] * f[k] + g[k] for k in range(4))
        rec["sourceColorSpace"] = "raw"
        rec["output"] = "rgb"
        return Tex(rec)

    # -- images
    def image(self, n: Node, output: str, kind: str):
        usd = n.category == "UsdUVTexture"
        file_src = n.input("file")
        path = file_src.value if isinstance(file_src.value, str) and file_src.value else None
        if usd:
            cs = str(n.input("sourceColorSpace").value or "auto")
            ws = str(n.input("wrapS").value or "useMetadata")
            wt = str(n.input("wrapT").value or "useMetadata")
            scale = as_tuple(n.input("scale").value, 4, 1.0)
            bias = as_tuple(n.input("bias").value, 4, 0.0)
            fb = n.input("fallback").value
            uv_src = n.input("st")
            out = output if output in ("rgb", "r", "g", "b", "a") else "rgb"
        else:
            colour = n.type in ("color3", "color4")
            # MaterialX colour-manages colour values only
            cs = (file_src.colorspace or "lin_rec709") if colour else "raw"
            ws = _ADDRESS.get(str(n.input("uaddressmode").value or "periodic"), "repeat")
            wt = _ADDRESS.get(str(n.input("vaddressmode").value or "periodic"), "repeat")
            if n.category == "tiledimage":
                ws = wt = "repeat"
            scale, bias = (1.0, 1.0, 1.0, 1.0), (0.0, 0.0, 0.0, 0.0)
            fb = n.input("default").value
            uv_src = n.input("texcoord")
            out = "r" if n.type == "float" else "rgb"
        st_xf, st_primvar = self.texcoord(uv_src, n)
        if n.category == "tiledimage":
            tiling = as_tuple(n.input("uvtiling").value, 2, 1.0)
            offset = as_tuple(n.input("uvoffset").value, 2, 0.0)
            rwi = as_tuple(n.input("realworldimagesize").value, 2, 1.0)
            rwt = as_tuple(n.input("realworldtilesize").value, 2, 1.0)
            k = [rwt[i] / rwi[i] if rwi[i] else 1.0 for i in range(2)]
            tile = (tiling[0] * k[0], 0.0, -offset[0] * k[0],
                    0.0, tiling[1] * k[1], -offset[1] * k[1])
            st_xf = _compose(tile, st_xf)
        if path is None:
            self.warn(f"node {n.path} ({n.category}) has no file; using its default")
        rec = {"texture": path, "shader": n.path, "output": out, "wrapS": ws, "wrapT": wt,
               "scale": scale, "bias": bias, "sourceColorSpace": cs,
               "st_primvar": st_primvar, "st_fallback": None, "st_transform": st_xf,
               "fallback": as_tuple(fb, 4, 0.0) if fb is not None else None,
               "unresolved": None if path is None or path.endswith("]") or "://" in path
               or os.path.exists(path) else path}
        return Tex(rec)

    def texcoord(self, src: Src, owner: Node, depth: int = 0):
        """(st transform, st primvar name) of an image's texture coordinates."""
        if src.node is None or depth > 16:
            return _IDENTITY, None
        n = src.node
        cat = n.category
        if cat == "texcoord":
            idx = int(as_float(n.input("index").value, 0.0))
            if idx != 0:
                self.warn(f"node {n.path} (texcoord) index {idx}: only the first uv set is "
                          f"read")
            return _IDENTITY, None
        if cat in ("geompropvalue", "UsdPrimvarReader"):
            name = n.input("geomprop" if cat == "geompropvalue" else "varname").value
            return _IDENTITY, (str(name) if name else None)
        if cat == "place2d":
            inner, pv = self.texcoord(n.input("texcoord"), n, depth + 1)
            return _compose(_place2d(n), inner), pv
        if cat in ("dot", "convert"):
            return self.texcoord(n.input("in"), n, depth + 1)
        if cat == "UsdTransform2d":
            from .shading import _transform2d_matrix
            inner, pv = self.texcoord(n.input("in"), n, depth + 1)
            return _compose(_transform2d_matrix(n.shader), inner) if isinstance(n, UsdNode) \
                else inner, pv
        self.warn(f"node {n.path} ({cat}) driving the texture coordinates of {owner.path} "
                  f"has no mapping; the mesh's st is used")
        return _IDENTITY, None


def scale_rec(rec: dict, k) -> dict:
    """A texture record times a constant (scalar or RGB): scale and bias."""
    kk = as_tuple(k, 3) + (1.0,)
    sc, bi = as_tuple(rec.get("scale"), 4, 1.0), as_tuple(rec.get("bias"), 4, 0.0)
    out = dict(rec)
    out["scale"] = tuple(sc[i] * kk[i] for i in range(4))
    out["bias"] = tuple(bi[i] * kk[i] for i in range(4))
    if out.get("fallback") is not None:
        fb = as_tuple(out["fallback"], 4)
        out["fallback"] = tuple(fb[i] * kk[i] for i in range(4))
    return out


def _compose(outer, inner):
    a, b, tx, c, d, ty = outer
    e, f, ux, g, h, uy = inner
    return (a * e + b * g, a * f + b * h, a * ux + b * uy + tx,
            c * e + d * g, c * f + d * h, c * ux + d * uy + ty)


def _place2d(n: Node):
    """MaterialX place2d as a 2x3 matrix. SRT (operationorder 0):
    st' = R((st - pivot) / scale) - offset + pivot; TRS (1):
    st' = R(st - pivot - offset) / scale + pivot; R turns by ``rotate``
    degrees clockwise (x' = c x + s y, y' = -s x + c y)."""
    px, py = as_tuple(n.input("pivot").value, 2, 0.0)
    sx, sy = as_tuple(n.input("scale").value, 2, 1.0)
    ox, oy = as_tuple(n.input("offset").value, 2, 0.0)
    rot = as_float(n.input("rotate").value, 0.0)
    order = n.input("operationorder").value
    c, s = math.cos(math.radians(rot)), math.sin(math.radians(rot))
    sx = sx if sx else 1.0
    sy = sy if sy else 1.0
    if str(order) in ("1", "TRS"):
        A = (c / sx, s / sx, -s / sy, c / sy)
        qx, qy = px + ox, py + oy
        return (A[0], A[1], -(A[0] * qx + A[1] * qy) + px,
                A[2], A[3], -(A[2] * qx + A[3] * qy) + py)
    A = (c / sx, s / sy, -s / sx, c / sy)
    return (A[0], A[1], -(A[0] * px + A[1] * py) - ox + px,
            A[2], A[3], -(A[2] * px + A[3] * py) - oy + py)
