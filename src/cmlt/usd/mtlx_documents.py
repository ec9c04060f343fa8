"""``.mtlx`` documents referenced from a stage: read with the ``materialx``
package through USD's asset resolver (a document may sit in a ``.usdz``), once
per file version, with the standard libraries attached; a binding target under
such a reference found in the document (usdMtlx's ``/MaterialX/Materials/<name>``
layout) as a :class:`MtlxMaterialRef`."""
from __future__ import annotations

import os
import threading
from typing import Any, Dict, List, Optional, Tuple

from .mtlx_graph import DocNode, mtlx_library

__all__ = ["load_document", "MtlxMaterialRef", "mtlx_references", "mtlx_binding"]

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

    def surface_node(self, label: str, warnings: List[str]) -> Optional[DocNode]:
        """The surface shader node of the material in its document, or None
        (warned, naming ``label``: the document cannot be read, has no such
        material or it has no surface shader)."""
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
        return DocNode(shader, self.doc_path)


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
