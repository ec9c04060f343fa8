"""MaterialX surfaces -> :class:`cmlt.scene.Material` (cmlt's UsdPreviewSurface model).

Two ways a stage carries MaterialX:

* UsdShade networks whose shader ids are MaterialX node definitions
  (``ND_open_pbr_surface_surfaceshader``, ``ND_image_color3`` ...), reached
  through the material's ``outputs:mtlx:surface`` (what usdMtlx and the DCC
  exporters write);
* ``.mtlx`` documents referenced from the stage
  (``references = @looks.mtlx@</MaterialX/Materials/Wood>``). usd-core ships
  no MaterialX file-format plugin, so such a reference does not compose
  ("Cannot determine file format"); the document is read here with the
  ``materialx`` package instead, through USD's asset resolver (it may sit in
  a ``.usdz``), and the binding's target path is mapped to the document's
  material (``/MaterialX/Materials/<name>``, usdMtlx's layout).

Both become one small graph (:class:`Node`), walked from the surface shader.

Mapping (``open_pbr_surface`` / ``standard_surface`` -> UsdPreviewSurface):

======================================  =====================================
base_color x base_weight (base)          diffuseColor (a texture: its scale)
base_metalness (metalness)               metallic
specular_roughness                       roughness
specular_ior (specular_IOR)              ior
specular_weight x specular_color         folded into the specular workflow
                                         (F0 = lerp(F0(ior) w c, base, metal),
                                         diffuse = (1 - metal) base) when base
                                         and metalness are constants, else
                                         ignored with a warning
coat_weight (coat), coat_roughness       clearcoat, clearcoatRoughness (white,
                                         IOR 1.5: coat_color/coat_ior warn)
transmission_weight (transmission)       opacity = 1 - transmission (the
                                         dielectric lobe, ior = specular_ior)
emission_luminance x emission_color      emissiveColor
(emission x emission_color)
geometry_opacity (opacity)               presence: with constant base and
                                         metalness exactly (specular workflow,
                                         ior 1 pass-through), else a cut-out at
                                         0.5 (opacityThreshold), with a warning
geometry_normal (normal) <- normalmap    normal (tangent-space map)
======================================  =====================================

Nodes understood in front of those inputs: ``image`` / ``tiledimage`` (file
with its colour space, default, address modes; ``texcoord``, ``place2d``,
``geompropvalue`` texture coordinates folded into the st transform / the st
primvar), ``normalmap``, ``geompropvalue`` (a primvar per vertex, like
UsdPrimvarReader), ``constant``, ``dot``, ``convert``, ``extract`` /
``separate3`` (one channel of a texture), ``multiply`` by a constant (folded
into the texture's scale). Anything else falls back to the input's value or
default, with a warning naming the node and the input. MaterialX's own
``UsdPreviewSurface`` / ``UsdUVTexture`` / ``UsdPrimvarReader`` nodes map
one to one.
"""
from __future__ import annotations

import math
import os
import threading
from typing import Any, Dict, List, Optional, Tuple

from ..scene import Material
from .color import to_rendering_space

__all__ = ["read_materialx_network", "mtlx_binding", "mtlx_references", "MtlxMaterialRef",
           "SURFACE_IDS", "mtlx_library"]

#: MaterialX surface shaders mapped onto the core's model
SURFACES = ("open_pbr_surface", "standard_surface", "UsdPreviewSurface")
SURFACE_IDS = ("ND_open_pbr_surface_surfaceshader", "ND_standard_surface_surfaceshader",
               "ND_UsdPreviewSurface_surfaceshader")

_lib_lock = threading.Lock()
_library = None


def mtlx_library():
    """The MaterialX standard libraries (node definitions), loaded once."""
    global _library
    with _lib_lock:
        if _library is None:
            import MaterialX as mx
            lib = mx.createDocument()
            mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(),
                             lib)
            _library = lib
        return _library


# ---------------------------------------------------------------- values

def _plain(v) -> Any:
    """A MaterialX / USD value as plain Python (float, int, bool, str, tuple)."""
    if v is None:
        return None
    if isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, float):
        return v if math.isfinite(v) else 0.0
    if hasattr(v, "asTuple"):
        v = v.asTuple()
    try:
        from pxr import Sdf
        if isinstance(v, Sdf.AssetPath):
            return v.resolvedPath or v.path
    except ImportError:                                  # pragma: no cover
        pass
    try:
        t = tuple(float(x) for x in v)
        return tuple(x if math.isfinite(x) else 0.0 for x in t)
    except TypeError:
        return str(v)


def _as_tuple(v, n: int, default=0.0) -> Tuple[float, ...]:
    if v is None:
        return (default,) * n
    if isinstance(v, (int, float, bool)):
        return (float(v),) * n
    t = tuple(float(x) for x in v)
    if len(t) == 1:
        return t * n
    return (t + (default,) * n)[:n]


def _as_float(v, default=0.0) -> float:
    if v is None:
        return default
    if isinstance(v, (int, float, bool)):
        return float(v)
    try:
        return float(tuple(v)[0])
    except (TypeError, IndexError, ValueError):
        return default


class Src:
    """Where an input's value comes from: a constant, or a node's output."""

    __slots__ = ("value", "node", "output", "colorspace", "authored", "name")

    def __init__(self, name, value=None, node=None, output="out", colorspace=None,
                 authored=False):
        self.name = name
        self.value = value
        self.node = node
        self.output = output or "out"
        self.colorspace = colorspace
        self.authored = authored


class Node:
    """A MaterialX node: ``category`` (``image``, ``open_pbr_surface`` ...),
    output ``type``, a ``path`` for messages, and its inputs (authored ones
    from the source, the rest from the node definition's defaults)."""

    category = ""
    type = ""
    path = ""
    nodedef = None

    def input(self, name: str) -> Src:                  # pragma: no cover - abstract
        raise NotImplementedError

    def authored_inputs(self) -> List[str]:              # pragma: no cover - abstract
        raise NotImplementedError

    def default(self, name: str):
        nd = self.nodedef
        if nd is None:
            return None
        i = nd.getActiveInput(name)
        if i is None or not i.hasValueString() or not i.getValueString():
            return None
        return _plain(i.getValue())

    def __repr__(self):
        return f"{self.path} ({self.category})"


class UsdNode(Node):
    """A UsdShade shader whose id is a MaterialX node definition."""

    def __init__(self, shader):
        from .shading import _shader_id
        self.shader = shader
        self.id = _shader_id(shader)
        self.path = str(shader.GetPath())
        self.nodedef = mtlx_library().getNodeDef(self.id) if self.id else None
        if self.nodedef is not None:
            self.category = self.nodedef.getNodeString()
            outs = self.nodedef.getActiveOutputs()
            self.type = outs[0].getType() if outs else ""
        else:
            self.category = self.id

    def authored_inputs(self) -> List[str]:
        return [i.GetBaseName() for i in self.shader.GetInputs()
                if i.GetAttr().HasAuthoredValue() or i.HasConnectedSource()]

    def input(self, name: str) -> Src:
        from pxr import UsdShade

        from .shading import _value_source
        inp = self.shader.GetInput(name)
        if inp and (inp.GetAttr().HasAuthoredValue() or inp.HasConnectedSource()):
            value, src, out = _value_source(inp)
            if src is not None:
                return Src(name, node=UsdNode(UsdShade.Shader(src.GetPrim())), output=out,
                           authored=True)
            attr = inp.GetAttr()
            cs = None
            if attr.HasColorSpace():
                cs = str(attr.GetColorSpace()) or None
            if cs is None:
                from ..color import authored_colorspace
                got = authored_colorspace(attr, default="")
                cs = got or None
            return Src(name, value=_plain(value), colorspace=cs, authored=True)
        return Src(name, value=self.default(name))


class DocNode(Node):
    """A node of a MaterialX document (``anchor``: the document's resolved
    path, against which relative file names resolve)."""

    def __init__(self, node, anchor: str):
        self.node = node
        self.anchor = anchor
        self.category = node.getCategory()
        self.type = node.getType()
        self.path = f"{anchor}:{node.getNamePath()}"
        try:
            self.nodedef = node.getNodeDef()
        except Exception:                                # pragma: no cover
            self.nodedef = None

    def authored_inputs(self) -> List[str]:
        return [i.getName() for i in self.node.getInputs()]

    def input(self, name: str) -> Src:
        inp = self.node.getInput(name)
        seen = 0
        while inp is not None and inp.hasInterfaceName() and seen < 16:
            iface = inp.getInterfaceInput()             # a nodegraph's own input
            if iface is None:
                break
            inp, seen = iface, seen + 1
        if inp is None:
            return Src(name, value=self.default(name))
        out = inp.getConnectedOutput()
        node = inp.getConnectedNode()
        if node is not None:
            oname = (out.getOutputString() if out is not None and out.hasOutputString()
                     else inp.getOutputString() if inp.hasOutputString() else "out")
            return Src(name, node=DocNode(node, self.anchor), output=oname or "out",
                       authored=True)
        if inp.getNodeName() or inp.hasNodeGraphString():
            return Src(name, value=self.default(name))   # dangling connection
        if inp.getType() == "filename":
            raw = inp.getResolvedValueString()
            return Src(name, value=_anchor(raw, self.anchor) if raw else None,
                       colorspace=inp.getActiveColorSpace() or None, authored=True)
        value = _plain(inp.getValue()) if inp.hasValueString() else self.default(name)
        return Src(name, value=value, colorspace=inp.getActiveColorSpace() or None,
                   authored=True)


def _anchor(path: str, anchor: str) -> str:
    """``path`` relative to the document ``anchor`` (inside its package when
    the document is a package member)."""
    from pxr import Ar
    if os.path.isabs(path) or "://" in path or path.endswith("]"):
        return path
    if anchor.endswith("]") and Ar.IsPackageRelativePath(anchor):
        outer, inner = Ar.SplitPackageRelativePathInner(anchor)
        joined = os.path.normpath(os.path.join(os.path.dirname(inner), path))
        return Ar.JoinPackageRelativePath([outer, joined])
    return os.path.normpath(os.path.join(os.path.dirname(anchor), path))


# ---------------------------------------------------------------- evaluation

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
_CHANNELS = "rgba"


class _Mapper:
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
            return _as_float(v)
        if kind == "colour":
            rgb = _as_tuple(v, 3)
            return to_rendering_space(rgb, src.colorspace or "lin_rec709")
        return _as_tuple(v, 3) if v is not None else None

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
            idx = int(_as_float(n.input("index").value, 0.0))
        else:
            idx = {"outr": 0, "outx": 0, "outg": 1, "outy": 1, "outb": 2, "outz": 2,
                   "outa": 3, "outw": 3}.get(output, 0)
        inner = self.eval(n, "in", "vector", depth + 1)
        if isinstance(inner, Tex):
            rec = dict(inner.rec)
            rec["output"] = _CHANNELS[max(0, min(idx, 3))]
            return Tex(rec)
        if isinstance(inner, Const):
            v = _as_tuple(inner.value, 4)
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
                x3, y3 = _as_tuple(x, 3), _as_tuple(y, 3)
                return Const(tuple(p * q for p, q in zip(x3, y3)))
            return Const(float(x) * float(y))
        if isinstance(a, Tex) and isinstance(b, Const):
            return Tex(_scale_rec(a.rec, b.value))
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
        s = _as_float(n.input("scale").value, 1.0) if n.input("scale").value is not None \
            else 1.0
        rec = dict(inner.rec)
        sc, bi = _as_tuple(rec.get("scale"), 4, 1.0), _as_tuple(rec.get("bias"), 4, 0.0)
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
            scale = _as_tuple(n.input("scale").value, 4, 1.0)
            bias = _as_tuple(n.input("bias").value, 4, 0.0)
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
            tiling = _as_tuple(n.input("uvtiling").value, 2, 1.0)
            offset = _as_tuple(n.input("uvoffset").value, 2, 0.0)
            rwi = _as_tuple(n.input("realworldimagesize").value, 2, 1.0)
            rwt = _as_tuple(n.input("realworldtilesize").value, 2, 1.0)
            k = [rwt[i] / rwi[i] if rwi[i] else 1.0 for i in range(2)]
            tile = (tiling[0] * k[0], 0.0, -offset[0] * k[0],
                    0.0, tiling[1] * k[1], -offset[1] * k[1])
            st_xf = _compose(tile, st_xf)
        if path is None:
            self.warn(f"node {n.path} ({n.category}) has no file; using its default")
        rec = {"texture": path, "shader": n.path, "output": out, "wrapS": ws, "wrapT": wt,
               "scale": scale, "bias": bias, "sourceColorSpace": cs,
               "st_primvar": st_primvar, "st_fallback": None, "st_transform": st_xf,
               "fallback": _as_tuple(fb, 4, 0.0) if fb is not None else None,
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
            idx = int(_as_float(n.input("index").value, 0.0))
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


def _scale_rec(rec: dict, k) -> dict:
    """A texture record times a constant (scalar or RGB): scale and bias."""
    kk = _as_tuple(k, 3) + (1.0,)
    sc, bi = _as_tuple(rec.get("scale"), 4, 1.0), _as_tuple(rec.get("bias"), 4, 0.0)
    out = dict(rec)
    out["scale"] = tuple(sc[i] * kk[i] for i in range(4))
    out["bias"] = tuple(bi[i] * kk[i] for i in range(4))
    if out.get("fallback") is not None:
        fb = _as_tuple(out["fallback"], 4)
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
    px, py = _as_tuple(n.input("pivot").value, 2, 0.0)
    sx, sy = _as_tuple(n.input("scale").value, 2, 1.0)
    ox, oy = _as_tuple(n.input("offset").value, 2, 0.0)
    rot = _as_float(n.input("rotate").value, 0.0)
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


# ---------------------------------------------------------------- surfaces

_DEFAULTS = {"diffuseColor": (0.18, 0.18, 0.18), "emissiveColor": (0.0, 0.0, 0.0),
             "specularColor": (0.0, 0.0, 0.0), "metallic": 0.0, "roughness": 0.5,
             "clearcoat": 0.0, "clearcoatRoughness": 0.01, "opacity": 1.0,
             "opacityThreshold": 0.0, "ior": 1.5, "useSpecularWorkflow": 0}

#: (open_pbr_surface name, standard_surface name) of every input the mapping reads
_NAMES = {
    "base_weight": ("base_weight", "base"), "base_color": ("base_color", "base_color"),
    "metalness": ("base_metalness", "metalness"),
    "specular_weight": ("specular_weight", "specular"),
    "specular_color": ("specular_color", "specular_color"),
    "roughness": ("specular_roughness", "specular_roughness"),
    "ior": ("specular_ior", "specular_IOR"),
    "coat": ("coat_weight", "coat"), "coat_color": ("coat_color", "coat_color"),
    "coat_roughness": ("coat_roughness", "coat_roughness"), "coat_ior": ("coat_ior", "coat_IOR"),
    "transmission": ("transmission_weight", "transmission"),
    "transmission_color": ("transmission_color", "transmission_color"),
    "emission": ("emission_luminance", "emission"),
    "emission_color": ("emission_color", "emission_color"),
    "opacity": ("geometry_opacity", "opacity"), "normal": ("geometry_normal", "normal"),
}


class _Surface:
    """The UsdPreviewSurface inputs being assembled: constants, texture and
    primvar records."""

    def __init__(self):
        self.values: Dict[str, Any] = {}
        self.records: Dict[str, dict] = {}

    def set(self, name, ev, mapper: _Mapper, kind: str, node: Node):
        from .shading import PRIMVAR_INPUTS, _primvar_request_record
        if ev is None:
            return
        if isinstance(ev, Const):
            self.values[name] = ev.value
        elif isinstance(ev, Tex):
            rec = dict(ev.rec)
            if kind == "scalar" and rec.get("output") == "rgb":
                rec["output"] = "r"
            self.records[name] = rec
            fb = rec.get("fallback")
            if fb is not None:
                self.values[name] = to_rendering_space(fb[:3], "lin_rec709") \
                    if kind == "colour" else \
                    fb[_CHANNELS.index(rec["output"])] if rec["output"] in _CHANNELS else fb[0]
        elif isinstance(ev, Prim):
            if not ev.varname:
                mapper.warn(f"{ev.node.path} ({ev.node.category}) names no primvar; {name} "
                            f"uses its default")
                return
            width = 3 if kind == "colour" else 1
            fb = _as_tuple(ev.fallback, width) if ev.fallback is not None else \
                _as_tuple(_DEFAULTS.get(name, 0.0), width)
            if kind == "colour":
                fb = to_rendering_space(fb, "lin_rec709")
            if name not in PRIMVAR_INPUTS:
                mapper.warn(f"input {name} reads primvar {ev.varname} through {ev.node.path}, "
                            f"which cmlt cannot vary over a surface for {name}; using "
                            f"{tuple(round(x, 6) for x in fb)}")
                self.values[name] = fb if width == 3 else fb[0]
                return
            self.records[name] = _primvar_request_record(name, ev.varname, fb, ev.node.path,
                                                         ev.node.category)
            self.values[name] = fb if width == 3 else fb[0]

    def constant(self, name):
        """The constant of ``name`` if it is one (no texture, no primvar)."""
        return None if name in self.records else self.values.get(name, _DEFAULTS[name])


def _map_physical(node: Node, mapper: _Mapper, std: bool) -> _Surface:
    k = 1 if std else 0

    def nm(key):
        return _NAMES[key][k]

    out = _Surface()
    ev = mapper.eval

    def cval(key, kind):
        """The constant value of an input, or None when something drives it."""
        src = node.input(nm(key))
        return None if src.node is not None else mapper.const(src, kind)

    # base colour x weight -> diffuseColor
    base = ev(node, nm("base_color"), "colour")
    w = cval("base_weight", "scalar")
    if w is None:
        mapper.warn(f"{node.path}: input {nm('base_weight')} is driven by a node; using 1")
        w = 1.0
    if isinstance(base, Const):
        base = Const(tuple(c * w for c in base.value))
    elif isinstance(base, Tex) and w != 1.0:
        base = Tex(_scale_rec(base.rec, w))
    out.set("diffuseColor", base, mapper, "colour", node)
    out.set("metallic", ev(node, nm("metalness"), "scalar"), mapper, "scalar", node)
    out.set("roughness", ev(node, nm("roughness"), "scalar"), mapper, "scalar", node)
    ior = cval("ior", "scalar")
    if ior is None:
        mapper.warn(f"{node.path}: input {nm('ior')} is driven by a node; using 1.5")
        ior = 1.5
    out.values["ior"] = ior

    # specular weight / colour: the specular workflow, exactly, for constant bases
    sw = cval("specular_weight", "scalar")
    sc = cval("specular_color", "colour")
    plain_spec = sw is not None and abs(sw - 1.0) < 1e-6 and sc is not None and _is_white(sc)
    foldable = out.constant("diffuseColor") is not None and out.constant("metallic") is not None

    # coat
    out.set("clearcoat", ev(node, nm("coat"), "scalar"), mapper, "scalar", node)
    out.set("clearcoatRoughness", ev(node, nm("coat_roughness"), "scalar"), mapper, "scalar",
            node)
    cc = cval("coat_color", "colour")
    if cc is None or not _is_white(cc):
        if _nonzero(out.values.get("clearcoat"), "clearcoat" in out.records):
            mapper.warn(f"{node.path}: input {nm('coat_color')} is not white; cmlt's coat is "
                        f"white (ignored)")
    ci = cval("coat_ior", "scalar")
    if ci is not None and abs(ci - 1.5) > 1e-3 and \
            _nonzero(out.values.get("clearcoat"), "clearcoat" in out.records):
        mapper.warn(f"{node.path}: input {nm('coat_ior')} = {ci:g}; cmlt's coat has IOR 1.5")

    # transmission -> (1 - opacity) dielectric lobe
    tr = cval("transmission", "scalar")
    if tr is None:
        mapper.warn(f"{node.path}: input {nm('transmission')} is driven by a node; "
                    f"transmission is constant in cmlt, using 0")
        tr = 0.0
    tr = min(max(tr, 0.0), 1.0)
    tc = cval("transmission_color", "colour")
    if tr > 0 and (tc is None or not _is_white(tc)):
        mapper.warn(f"{node.path}: input {nm('transmission_color')} is not white; cmlt's "
                    f"transmission is white (ignored)")

    # emission
    lum = cval("emission", "scalar")
    if lum is None:
        mapper.warn(f"{node.path}: input {nm('emission')} is driven by a node; using 0")
        lum = 0.0
    if lum > 0:
        ec = ev(node, nm("emission_color"), "colour")
        if isinstance(ec, Const):
            ec = Const(tuple(c * lum for c in ec.value))
        elif isinstance(ec, Tex):
            ec = Tex(_scale_rec(ec.rec, lum))
        elif isinstance(ec, Prim):
            ec = Prim(ec.varname, ec.fallback, ec.node)
        out.set("emissiveColor", ec, mapper, "colour", node)
    else:
        out.values["emissiveColor"] = (0.0, 0.0, 0.0)

    # normal map
    nsrc = node.input(nm("normal"))
    if nsrc.node is not None:
        nev = mapper.eval_source(nsrc, node, nm("normal"), "vector", 0)
        if isinstance(nev, Tex):
            out.records["normal"] = nev.rec
        elif nev is not None:
            mapper.warn(f"{node.path}: input {nm('normal')} is not a tangent-space normal map; "
                        f"ignored")

    # presence (opacity)
    pres_src = node.input(nm("opacity"))
    pres = None
    if pres_src.node is not None:
        pres = mapper.eval_source(pres_src, node, nm("opacity"), "scalar", 0)
    else:
        pv = pres_src.value
        pres = Const(sum(_as_tuple(pv, 3, 1.0)) / 3.0 if std else _as_float(pv, 1.0))

    spec_workflow = False
    if not plain_spec:
        if foldable and sw is not None and sc is not None:
            spec_workflow = True
        else:
            mapper.warn(f"{node.path}: inputs {nm('specular_weight')}/{nm('specular_color')} "
                        f"are not 1/white but the base colour or metalness is driven by a node; "
                        f"specular weight and colour are ignored")

    presence_const = pres.value if isinstance(pres, Const) else None
    if presence_const is not None and presence_const < 1.0:
        if tr > 0:
            mapper.warn(f"{node.path}: both {nm('transmission')} and {nm('opacity')} < 1; "
                        f"cmlt has one transmission lobe, {nm('opacity')} is ignored")
        elif foldable and sw is not None and sc is not None:
            spec_workflow = True
        else:
            mapper.warn(f"{node.path}: constant {nm('opacity')} {presence_const:g} with a "
                        f"base driven by a node: rendered as a cut-out at 0.5")
            out.values["opacity"] = presence_const
            out.values["opacityThreshold"] = 0.5
    elif isinstance(pres, (Tex, Prim)):
        if tr > 0:
            mapper.warn(f"{node.path}: both {nm('transmission')} and a varying {nm('opacity')}; "
                        f"{nm('opacity')} is ignored")
        else:
            out.set("opacity", pres, mapper, "scalar", node)
            out.values["opacityThreshold"] = 0.5
            mapper.warn(f"{node.path}: {nm('opacity')} varies over the surface: rendered as a "
                        f"cut-out at 0.5 (opacityThreshold)")

    if spec_workflow:
        base_c = out.constant("diffuseColor")
        metal = min(max(float(out.constant("metallic")), 0.0), 1.0)
        f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior > 0 else 0.0
        spec = tuple(min(1.0, max(0.0, f0 * sw * c)) for c in sc)
        out.values["specularColor"] = tuple((1 - metal) * s + metal * b
                                            for s, b in zip(spec, base_c))
        out.values["diffuseColor"] = tuple((1 - metal) * b for b in base_c)
        out.values["metallic"] = 0.0
        out.values["useSpecularWorkflow"] = 1
        if presence_const is not None and presence_const < 1.0 and tr == 0:
            out.values["opacity"] = presence_const
            out.values["ior"] = 1.0                    # presence: a pass-through
    if tr > 0:
        out.values["opacity"] = 1.0 - tr

    _warn_unmapped(node, mapper, std)
    return out


def _is_white(rgb) -> bool:
    w = to_rendering_space((1.0, 1.0, 1.0), "lin_rec709")
    return all(abs(a - b) < 1e-4 for a, b in zip(rgb, w))


def _nonzero(v, driven: bool) -> bool:
    return driven or (v is not None and float(v) > 0)


#: inputs the mapping reads (the rest warns when authored off its default)
_READ = {name for pair in _NAMES.values() for name in pair}


def _warn_unmapped(node: Node, mapper: _Mapper, std: bool):
    for name in node.authored_inputs():
        if name in _READ:
            continue
        src = node.input(name)
        if src.node is None:
            d = node.default(name)
            if d is None or _same_value(src.value, d):
                continue
            what = f"= {_fmt(src.value)}"
        else:
            what = f"is driven by {src.node.path}"
        mapper.warn(f"{node.path}: input {name} {what} has no mapping in cmlt's "
                    f"UsdPreviewSurface model; ignored")


def _same_value(a, b) -> bool:
    if isinstance(a, (tuple, list)) or isinstance(b, (tuple, list)):
        try:
            return all(abs(float(x) - float(y)) < 1e-6 for x, y in
                       zip(_as_tuple(a, 4), _as_tuple(b, 4)))
        except (TypeError, ValueError):
            return a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return abs(float(a) - float(b)) < 1e-6
    return a == b


def _fmt(v) -> str:
    if isinstance(v, tuple):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _map_preview(node: Node, mapper: _Mapper) -> _Surface:
    """MaterialX's UsdPreviewSurface node: one to one."""
    out = _Surface()
    colour = ("diffuseColor", "emissiveColor", "specularColor")
    for name in ("diffuseColor", "emissiveColor", "specularColor", "metallic", "roughness",
                 "clearcoat", "clearcoatRoughness", "opacity", "opacityThreshold", "ior",
                 "useSpecularWorkflow"):
        kind = "colour" if name in colour else "scalar"
        src = node.input(name)
        if src.node is None:
            if src.value is not None:
                out.values[name] = mapper.const(src, kind)
            continue
        if name in ("opacityThreshold", "ior", "useSpecularWorkflow"):
            mapper.warn(f"{node.path}: input {name} is driven by a node; using its default")
            continue
        out.set(name, mapper.eval(node, name, kind), mapper, kind, node)
    nsrc = node.input("normal")
    if nsrc.node is not None:
        nev = mapper.eval_source(nsrc, node, "normal", "vector", 0)
        if isinstance(nev, Tex):
            rec = dict(nev.rec)
            rec["sourceColorSpace"] = "raw"
            out.records["normal"] = rec
    return out


def map_surface(node: Node, material: str, warnings: List[str]) -> Optional[Material]:
    """A MaterialX surface shader node -> Material, or None (not a surface we
    map: warned)."""
    mapper = _Mapper(material, warnings)
    cat = node.category
    if cat == "open_pbr_surface":
        surf = _map_physical(node, mapper, std=False)
    elif cat == "standard_surface":
        surf = _map_physical(node, mapper, std=True)
    elif cat == "UsdPreviewSurface":
        surf = _map_preview(node, mapper)
    else:
        warnings.append(f"{material}: surface shader {node.path} ({cat or 'unknown node'}) has "
                        f"no mapping in cmlt (open_pbr_surface, standard_surface and "
                        f"UsdPreviewSurface have); rendered with the default grey material")
        return None
    v = surf.values

    def col(name):
        x = v.get(name, _DEFAULTS[name])
        return tuple(float(c) for c in _as_tuple(x, 3))

    def sca(name):
        x = _as_float(v.get(name, _DEFAULTS[name]), _DEFAULTS[name])
        return x if math.isfinite(x) else float(_DEFAULTS[name])

    inputs: Dict[str, Any] = dict(surf.records)
    inputs["materialx"] = {"shader": node.path, "category": cat}
    for name, rec in surf.records.items():
        if rec.get("unresolved"):
            warnings.append(f"{material}: texture {rec['unresolved']} for {name} (node "
                            f"{rec['shader']}) cannot be resolved; using the fallback value")
    return Material(
        name=material, diffuse=col("diffuseColor"), emission=col("emissiveColor"),
        specular=col("specularColor"),
        use_specular_workflow=bool(int(sca("useSpecularWorkflow"))),
        metallic=sca("metallic"), roughness=sca("roughness"), clearcoat=sca("clearcoat"),
        clearcoat_roughness=sca("clearcoatRoughness"), opacity=sca("opacity"),
        opacity_threshold=sca("opacityThreshold"), ior=sca("ior"), inputs=inputs)


# ---------------------------------------------------------------- UsdShade networks

def mtlx_surface_shader(material):
    """The surface shader of a UsdShade material's ``mtlx`` render context
    (or of its universal output when that is a MaterialX node), or None."""
    from pxr import UsdShade

    from .shading import _shader_id
    try:
        src, _, _ = material.ComputeSurfaceSource(["mtlx"])
    except Exception:                                    # pragma: no cover
        src = None
    if src and _shader_id(src).startswith("ND_"):
        return src
    for out in material.GetSurfaceOutputs():
        for sinfo in out.GetConnectedSources()[0]:
            shader = UsdShade.Shader(sinfo.source.GetPrim())
            if shader and _shader_id(shader).startswith("ND_"):
                return shader
    return None


def read_materialx_network(material, time, warnings: List[str]):
    """(is MaterialX, Material or None) for a UsdShade material whose surface
    is a MaterialX node network or whose prim references a ``.mtlx``
    document; (False, None) for anything else. None with True: the surface
    could not be mapped (warned)."""
    path = str(material.GetPath())
    shader = mtlx_surface_shader(material)
    if shader is not None:
        return True, map_surface(UsdNode(shader), path, warnings)
    ref = mtlx_binding(material.GetPrim().GetStage(), material.GetPath())
    if ref is not None:
        return True, ref.read(time, warnings, name=path)
    return False, None


# ---------------------------------------------------------------- .mtlx documents

_doc_lock = threading.Lock()
_docs: Dict[Tuple, Any] = {}


def load_document(resolved: str):
    """A MaterialX document (read once per file version; package members
    through ``Ar``), with the standard libraries attached."""
    import MaterialX as mx

    from .assets import is_package_path, read_asset
    key: Tuple = (resolved,)
    if not is_package_path(resolved):
        try:
            st = os.stat(resolved)
            key = (resolved, st.st_size, st.st_mtime_ns)
        except OSError:
            pass
    with _doc_lock:
        doc = _docs.get(key)
        if doc is not None:
            return doc
    doc = mx.createDocument()
    try:
        if is_package_path(resolved):
            mx.readFromXmlString(doc, read_asset(resolved).decode("utf-8"))
        else:
            mx.readFromXmlFile(doc, resolved)
    except Exception as exc:
        raise OSError(f"{resolved}: cannot read the MaterialX document "
                      f"({' '.join(str(exc).split())})") from None
    doc.setDataLibrary(mtlx_library())
    with _doc_lock:
        _docs[key] = doc
    return doc


class MtlxMaterialRef:
    """A material of a ``.mtlx`` document that a binding points at (through
    a reference usd-core could not compose). Stands where a
    ``UsdShade.Material`` would (``GetPath``)."""

    def __init__(self, target, doc_path: str, name: Optional[str], via: str):
        self.target = target                # the binding target (Sdf.Path)
        self.doc_path = doc_path            # resolved path of the .mtlx
        self.name = name                    # material name in the document (None: the only one)
        self.via = via                      # the prim whose reference names the document

    def GetPath(self):
        return self.target

    def read(self, time, warnings: List[str], name: Optional[str] = None) -> Optional[Material]:
        label = name or str(self.target)
        try:
            doc = load_document(self.doc_path)
        except OSError as exc:
            warnings.append(f"{label}: {exc}; rendered with the default grey material")
            return None
        mats = [n for n in doc.getNodes() if n.getType() == "material"]
        if self.name is not None:
            found = [n for n in mats if n.getName() == self.name]
        else:
            found = mats if len(mats) == 1 else []
        if not found:
            names = ", ".join(n.getName() for n in mats) or "none"
            warnings.append(f"{label}: {self.via} references {self.doc_path}, which has no "
                            f"material {self.name or '(several; name one)'} (it has {names}); "
                            f"rendered with the default grey material")
            return None
        mat = found[0]
        sin = mat.getInput("surfaceshader")
        shader = sin.getConnectedNode() if sin is not None else None
        if shader is None:
            warnings.append(f"{label}: material {mat.getName()} of {self.doc_path} has no "
                            f"surface shader; rendered with the default grey material")
            return None
        return map_surface(DocNode(shader, self.doc_path), label, warnings)


def mtlx_references(prim):
    """(resolved document path, prim path in it, layer) of every reference
    of ``prim`` to a ``.mtlx`` file, strongest first."""
    from pxr import Ar, Sdf
    out = []
    for spec in prim.GetPrimStack():
        refs = spec.referenceList
        items = list(refs.explicitItems) + list(refs.prependedItems) + list(refs.appendedItems)
        for ref in items:
            ap = ref.assetPath
            if not ap or not ap.lower().endswith(".mtlx"):
                continue
            ident = Sdf.ComputeAssetPathRelativeToLayer(spec.layer, ap)
            resolved = str(Ar.GetResolver().Resolve(ident)) or ident
            out.append((resolved, ref.primPath, spec.layer))
    return out


def mtlx_binding(stage, target) -> Optional[MtlxMaterialRef]:
    """The .mtlx material a binding target stands for: the target itself or
    an ancestor references a ``.mtlx`` document; the rest of the path below
    that prim, appended to the referenced prim path (``/MaterialX`` when
    none is named), is usdMtlx's ``/MaterialX/Materials/<name>``."""
    from pxr import Sdf
    target = Sdf.Path(str(target))
    p = target
    while p and p != Sdf.Path.absoluteRootPath:
        prim = stage.GetPrimAtPath(p)
        if prim:
            refs = mtlx_references(prim)
            if refs:
                resolved, prim_path, _ = refs[0]
                base = prim_path if prim_path and not prim_path.isEmpty else \
                    Sdf.Path("/MaterialX")
                rel = target.MakeRelativePath(p)
                full = base if str(rel) in ("", ".") else base.AppendPath(rel)
                elems = [e for e in str(full).split("/") if e]
                name = None
                if len(elems) >= 3 and elems[1] == "Materials":
                    name = elems[2]
                elif len(elems) == 1:
                    name = None                     # the whole document: its only material
                else:
                    name = elems[-1]
                return MtlxMaterialRef(target, resolved, name, str(p))
        p = p.GetParentPath()
    return None
