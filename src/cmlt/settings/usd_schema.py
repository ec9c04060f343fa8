"""The ``CmltRenderSettingsAPI`` schema files, written from the settings table.

usd-core ships no ``usdGenSchema``, so both files of the codeless schema are
generated here from the stage settings of the table (:data:`cmlt.settings.FIELDS`):
``schema.usda`` (the schema's input form) and ``generatedSchema.usda`` (the
flattened form USD reads at run time). Regenerate after editing the table::

    python -m cmlt.settings.usd_schema --write     # rewrite plugins/usd/cmltSchemas/resources
    python -m cmlt.settings.usd_schema --check     # exit 1 if the files are stale

``tests/python/settings`` fails when the files on disk are not what this
module writes, and when USD reads something else from them than the table says.
"""
from __future__ import annotations

import argparse
import os
import sys
from typing import Dict, Iterable

from .table import FIELDS, SCHEMA_NAME, SettingField

__all__ = ["schema_files", "schema_dir", "write", "stale_files", "range_words"]

_CLASS_DOC = ("cmlt render settings on a UsdRender.Settings prim: integrator, sample "
              "budget, Metropolis parameters and the sequence (frame to frame) options. "
              "Command-line flags override these values; unauthored attributes take the "
              "fallbacks below. Written from the settings table "
              "(src/core/integrators/common/render_settings.h) by "
              "python -m cmlt.settings.usd_schema --write.")


def _num(x) -> str:
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def range_words(f: SettingField) -> str:
    """The valid range of a numeric setting as the schema states it ('' for
    tokens and bools)."""
    if f.kind in ("token", "bool"):
        return ""
    if f.kind == "uint64":
        return "Range 0 .. 2^64-1."
    if f.hi is None or (f.kind == "int" and f.hi == 2 ** 31 - 1):
        return f"Range {'>' if f.lo_open else '>='} {_num(f.lo)}."
    if f.kind == "int":
        return f"Range {_num(f.lo)} .. {_num(f.hi)}."
    return f"Range {'(' if f.lo_open else '['}{_num(f.lo)}, {_num(f.hi)}]."


def _doc(f: SettingField) -> str:
    text = f.doc + "."
    words = range_words(f)
    return f"{text} {words}" if words else text


def _value(f: SettingField) -> str:
    if f.kind == "token":
        return f'"{f.default}"'
    if f.kind == "bool":
        return "1" if f.default else "0"
    return _num(f.default) if f.kind == "double" else str(int(f.default))


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _attribute(f: SettingField) -> Iterable[str]:
    yield f"    uniform {f.kind} {f.attr} = {_value(f)} ("
    if f.kind == "token":
        yield "        allowedTokens = [" + ", ".join(f'"{t}"' for t in f.tokens) + "]"
    yield f"        doc = {_quote(_doc(f))}"
    yield "    )"


def schema_files() -> Dict[str, str]:
    """``{file name: text}`` of the schema's two files."""
    attrs = [line for f in FIELDS for line in _attribute(f)]
    schema = [
        "#usda 1.0",
        "(",
        '    """cmlt USD schemas, in the input form of usdGenSchema (generated: see',
        '    generatedSchema.usda)."""',
        "    subLayers = [",
        "        @usd/schema.usda@",
        "    ]",
        ")",
        "",
        'over "GLOBAL" (',
        "    customData = {",
        '        string libraryName = "cmltSchemas"',
        '        string libraryPath = "."',
        "        bool skipCodeGeneration = true",
        "    }",
        ")",
        "{",
        "}",
        "",
        f'class "{SCHEMA_NAME}" (',
        "    inherits = </APISchemaBase>",
        f"    doc = {_quote(_CLASS_DOC)}",
        "    customData = {",
        '        token apiSchemaType = "singleApply"',
        '        token[] apiSchemaCanOnlyApplyTo = ["RenderSettings"]',
        "    }",
        ")",
        "{",
        *attrs,
        "}",
    ]
    generated = [
        "#usda 1.0",
        "(",
        '    "The flattened form of schema.usda that USD reads (usd-core ships no '
        'usdGenSchema). Do not edit: python -m cmlt.settings.usd_schema --write writes '
        'both files from the settings table, and tests/python/settings checks them."',
        ")",
        "",
        f'class "{SCHEMA_NAME}" (',
        f"    doc = {_quote(_CLASS_DOC)}",
        ")",
        "{",
        *attrs,
        "}",
    ]
    return {"schema.usda": "\n".join(schema) + "\n",
            "generatedSchema.usda": "\n".join(generated) + "\n"}


def schema_dir() -> str:
    """``plugins/usd/cmltSchemas/resources`` of the plugin path in use."""
    from .. import _plugins
    path = _plugins.plugin_path()
    if path is None:
        raise FileNotFoundError("cmlt's USD plugins (plugins/usd) were not found")
    return os.path.join(path, "cmltSchemas", "resources")


def stale_files(directory: str = "") -> list:
    """The schema files in ``directory`` that differ from :func:`schema_files`."""
    directory = directory or schema_dir()
    stale = []
    for name, text in schema_files().items():
        path = os.path.join(directory, name)
        try:
            with open(path, encoding="utf-8") as fh:
                current = fh.read()
        except FileNotFoundError:
            current = None
        if current != text:
            stale.append(path)
    return stale


def write(directory: str = "") -> list:
    """Write both files into ``directory`` (default :func:`schema_dir`)."""
    directory = directory or schema_dir()
    written = []
    for name, text in schema_files().items():
        path = os.path.join(directory, name)
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(text)
        written.append(path)
    return written


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m cmlt.settings.usd_schema",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--write", action="store_true", help="rewrite the schema files")
    ap.add_argument("--check", action="store_true", help="exit 1 if they are stale")
    ap.add_argument("--dir", default="", help="the resources directory (default: the plugin's)")
    args = ap.parse_args(argv)
    if args.write:
        for path in write(args.dir):
            print(f"wrote {path}")
        return 0
    stale = stale_files(args.dir)
    for path in stale:
        print(f"stale: {path} (run python -m cmlt.settings.usd_schema --write)")
    return 1 if (stale and args.check) else 0


if __name__ == "__main__":
    sys.exit(main())
