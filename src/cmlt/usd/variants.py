"""Variant selections chosen at render time (``--variant``), the variant sets a
stage offers (``cmlt inspect``), and the render settings prim chosen at render
time (``-R``/``--settings``, :func:`select_render_settings`).

A selection is authored in the stage's session layer, the strongest layer
of the stage and one that is never saved, so the shot's own files are not
touched and USD recomposes what the selection changes (its geometry,
materials, nested variant sets). Specs, in the order given:

* ``SET=VALUE`` selects VALUE on every prim that has a variant set SET,
  including prims that only appear once an earlier selection is made
  (nested variant sets), until nothing changes;
* ``/prim/path:SET=VALUE`` (or USD's own spelling ``/prim/path{SET=VALUE}``)
  selects it on that prim only.

A spec that names no variant set of the stage, a prim that does not exist,
or a variant the set does not have is a :class:`VariantError` naming the
spec and listing what there is. Prims inside instances (instance proxies)
share their prototype and cannot take their own selection: the instance
prim (or an unqualified ``SET=VALUE``, which reaches it) must carry it.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable, List, Optional, Tuple

from pxr import Sdf, Usd, UsdRender

from .errors import UsdLoadError

__all__ = ["VariantError", "VariantSpec", "parse_variant", "apply_variants", "variant_sets",
           "select_render_settings"]

#: passes of an unqualified SET=VALUE over the stage: each may reveal prims of
#: the variant just selected that carry the same set
_MAX_PASSES = 32

_IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*$")


class VariantError(UsdLoadError):
    """A ``--variant`` spec (or ``--settings`` path) that cannot be applied (a
    usage error: the message names the flag and what the stage offers instead)."""


@dataclass(frozen=True)
class VariantSpec:
    """One ``--variant``: ``prim`` is None for every prim with the set."""

    variant_set: str
    value: str
    prim: Optional[str] = None
    text: str = ""

    def __str__(self) -> str:
        return self.text or (f"{self.prim}:" if self.prim else "") + \
            f"{self.variant_set}={self.value}"


def parse_variant(text: str) -> VariantSpec:
    """``SET=VALUE``, ``/prim:SET=VALUE`` or ``/prim{SET=VALUE}`` -> a spec;
    ValueError (one line, quoting the text) if it is none of them."""
    raw = str(text).strip()
    prim = None
    body = raw
    m = re.match(r"^(/[^{}]*)\{([^{}]*)\}$", raw)
    if m:
        prim, body = m.group(1), m.group(2)
    elif raw.startswith("/"):
        if ":" not in raw:
            raise ValueError(f"{raw!r}: a prim-qualified variant is /PRIM:SET=VALUE")
        prim, body = raw.split(":", 1)
    if "=" not in body:
        raise ValueError(f"{raw!r} is not SET=VALUE (or /PRIM:SET=VALUE), e.g. "
                         "modelingVariant=Cube")
    vset, value = (s.strip() for s in body.split("=", 1))
    if not _IDENT.match(vset):
        raise ValueError(f"{raw!r}: {vset!r} is not a variant set name")
    if not value:
        raise ValueError(f"{raw!r}: no variant after '=' (SET=VALUE)")
    if prim is not None:
        prim = prim.rstrip("/") or "/"
        if not (Sdf.Path.IsValidPathString(prim) and Sdf.Path(prim).IsAbsolutePath()
                and Sdf.Path(prim).IsPrimPath()):
            raise ValueError(f"{raw!r}: {prim!r} is not an absolute prim path")
    return VariantSpec(variant_set=vset, value=value, prim=prim, text=raw)


def _as_spec(spec) -> VariantSpec:
    if isinstance(spec, VariantSpec):
        return spec
    try:
        return parse_variant(spec)
    except ValueError as exc:
        raise VariantError(f"--variant {exc}") from None


def _names(prim, vset: str) -> List[str]:
    return list(prim.GetVariantSets().GetVariantSet(vset).GetVariantNames())


def _check_value(spec: VariantSpec, prim, where: str) -> None:
    names = _names(prim, spec.variant_set)
    if spec.value not in names:
        raise VariantError(f"--variant {spec}: {prim.GetPath()} has no variant {spec.value!r} "
                           f"in its set {spec.variant_set!r} (it has: "
                           f"{', '.join(names) or 'none'}) in {where}")


def _author(stage, selections: Iterable[Tuple[Sdf.Path, str, str]]) -> None:
    """Write the selections into the session layer in one change block (one
    recomposition)."""
    layer = stage.GetSessionLayer()
    with Sdf.ChangeBlock():
        for path, vset, value in selections:
            spec = Sdf.CreatePrimInLayer(layer, path)
            spec.variantSelections[vset] = value


def _stage_sets(stage) -> List[str]:
    found = []
    for prim in Usd.PrimRange(stage.GetPseudoRoot()):
        if prim.HasVariantSets():
            for n in prim.GetVariantSets().GetNames():
                if n not in found:
                    found.append(n)
    return found


def _apply_one(stage, spec: VariantSpec, where: str) -> List[Tuple[str, str, str]]:
    applied: List[Tuple[str, str, str]] = []
    if spec.prim is not None:
        prim = stage.GetPrimAtPath(spec.prim)
        if not prim:
            raise VariantError(f"--variant {spec}: no prim {spec.prim} in {where}")
        if prim.IsInstanceProxy():
            raise VariantError(f"--variant {spec}: {spec.prim} is inside an instance (its "
                               "prototype is shared); select the variant on the instance prim")
        sets = list(prim.GetVariantSets().GetNames())
        if spec.variant_set not in sets:
            raise VariantError(f"--variant {spec}: {spec.prim} has no variant set "
                               f"{spec.variant_set!r} (it has: {', '.join(sets) or 'none'}) "
                               f"in {where}")
        _check_value(spec, prim, where)
        _author(stage, [(prim.GetPath(), spec.variant_set, spec.value)])
        return [(str(prim.GetPath()), spec.variant_set, spec.value)]
    seen = False
    for _ in range(_MAX_PASSES):
        todo = []
        for prim in Usd.PrimRange(stage.GetPseudoRoot()):
            if not prim.HasVariantSets():
                continue
            vsets = prim.GetVariantSets()
            if not vsets.HasVariantSet(spec.variant_set):
                continue
            seen = True
            _check_value(spec, prim, where)
            if vsets.GetVariantSelection(spec.variant_set) != spec.value:
                todo.append((prim.GetPath(), spec.variant_set, spec.value))
        if not todo:
            break
        _author(stage, todo)
        applied.extend((str(p), s, v) for p, s, v in todo)
    if not seen:
        sets = _stage_sets(stage)
        raise VariantError(f"--variant {spec}: no prim of {where} has a variant set "
                           f"{spec.variant_set!r} (variant sets: {', '.join(sets) or 'none'})")
    return applied


def apply_variants(stage, specs, where: str = "the stage") -> List[Tuple[str, str, str]]:
    """Apply ``--variant`` specs (strings or :class:`VariantSpec`) in order in
    the session layer of ``stage``; returns the (prim, set, variant) selections
    authored. Raises :class:`VariantError`."""
    applied: List[Tuple[str, str, str]] = []
    for s in specs or ():
        applied.extend(_apply_one(stage, _as_spec(s), where))
    return applied


def variant_sets(stage) -> List[Tuple[str, str, str, List[str]]]:
    """Every variant set of the composed stage: (prim path, set name,
    selection ('' if none), variant names), in traversal order. Prims inside
    instances are listed once, under their prototype's instance."""
    out = []
    for prim in Usd.PrimRange(stage.GetPseudoRoot()):
        if not prim.HasVariantSets():
            continue
        vsets = prim.GetVariantSets()
        for name in vsets.GetNames():
            out.append((str(prim.GetPath()), name, vsets.GetVariantSelection(name),
                        _names(prim, name)))
    return out


def select_render_settings(stage, path: str, where: str = "the stage") -> None:
    """Make ``path`` the stage's render settings (``-R``/``--settings``): author
    ``renderSettingsPrimPath`` in the session layer, which every reader of the
    settings honours; :class:`VariantError` (a usage error) naming the path and
    listing the stage's RenderSettings prims if it is not one of them."""
    ok = Sdf.Path.IsValidPathString(path) and Sdf.Path(path).IsAbsolutePath()
    prim = stage.GetPrimAtPath(path) if ok else None
    if not prim or not prim.IsA(UsdRender.Settings):
        found = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdRender.Settings)]
        what = "no prim" if not prim else f"a {prim.GetTypeName() or 'typeless'} prim"
        raise VariantError(f"--settings {path}: {what} at that path in {where}, not "
                           f"RenderSettings (RenderSettings prims: {', '.join(found) or 'none'})")
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        stage.SetMetadata("renderSettingsPrimPath", str(prim.GetPath()))
