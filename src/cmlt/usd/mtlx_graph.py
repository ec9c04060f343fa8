"""The graph a MaterialX surface is walked in: :class:`Node` over a UsdShade
network of ``ND_*`` shaders (:class:`UsdNode`) or over a node of a ``.mtlx``
document (:class:`DocNode`), its inputs as plain values or :class:`Src`
connections, and the value helpers the evaluation and the mapping share
(:mod:`cmlt.usd.materialx`)."""
from __future__ import annotations

import os
import threading
from typing import Any, List, Tuple

from .shading import _plain as plain_usd_value

__all__ = ["Node", "UsdNode", "DocNode", "Src", "mtlx_library", "as_float", "as_tuple"]

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
    if hasattr(v, "asTuple"):                            # MaterialX vectors and colours
        v = v.asTuple()
    return plain_usd_value(v)


def as_tuple(v, n: int, default=0.0) -> Tuple[float, ...]:
    if v is None:
        return (default,) * n
    if isinstance(v, (int, float, bool)):
        return (float(v),) * n
    t = tuple(float(x) for x in v)
    if len(t) == 1:
        return t * n
    return (t + (default,) * n)[:n]


def as_float(v, default=0.0) -> float:
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
