"""The PLC's Structured Text parses with blark and declares exactly what plc_contract says.

Every protocols/st/*.st file is parsed, so files added later are covered too.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from blark.parse import parse
from blark.transform import (
    DataTypeDeclaration,
    EnumeratedTypeDeclaration,
    GlobalVariableDeclarations,
    StructureTypeDeclaration,
)

from protocols import plc_contract

ST_DIR = Path(__file__).resolve().parents[1] / "protocols" / "st"
ST_FILES = sorted(ST_DIR.glob("*.st"))
_ARRAY = re.compile(r"ARRAY\s*\[\s*(\S+?)\s*\.\.\s*(\S+?)\s*\]\s*OF\s+(\w+)", re.IGNORECASE)


@dataclass
class Declarations:
    """What the ST files declare; types as the declaration's text."""

    structs: dict[str, dict[str, str]] = field(default_factory=dict)  # struct -> member -> type
    enums: dict[str, tuple[str, dict[str, int]]] = field(default_factory=dict)  # enum -> (base, values)
    globals: dict[str, dict[str, str]] = field(default_factory=dict)  # GVL -> variable -> type
    constants: dict[str, int] = field(default_factory=dict)  # "GVL.name" -> value


def _integer(text: str) -> int:
    """An IEC integer literal: 42, 16#2A, UDINT#42."""
    text = text.split("#", 1)[1] if re.match(r"^[A-Z]+#", text) else text
    if text.startswith("16#"):
        return int(text[3:].replace("_", ""), 16)
    return int(text.replace("_", ""))


def _type_text(init) -> str:
    return str(getattr(init, "spec", init))


@functools.cache
def parse_st(path: Path) -> tuple:
    """The blark parse of one Structured Text file, transformed; each file is parsed once a
    session (the declarations, the parse test and the correction planner's test share it)."""
    results = list(parse(path))
    errors = [r.exception for r in results if r.exception is not None]
    assert results and not errors, f"{path.name}: {errors}"
    return tuple(r.transform() for r in results)



def _collect(paths: list[Path]) -> Declarations:
    decls = Declarations()
    for path in paths:
        for source in parse_st(path):
            for item in source.items:
                if isinstance(item, GlobalVariableDeclarations):
                    variables = decls.globals.setdefault(item.name, {})
                    for decl in item.items:
                        for name in decl.spec.variables:
                            variables[str(name)] = _type_text(decl.init)
                            value = getattr(decl.init, "value", None)
                            if item.attrs is not None and "CONSTANT" in str(item.attrs).upper():
                                decls.constants[f"{item.name}.{name}"] = _integer(str(value))
                elif isinstance(item, DataTypeDeclaration):
                    _collect_type(item.declaration, decls)
    return decls


def _collect_type(declaration, decls: Declarations) -> None:
    if isinstance(declaration, StructureTypeDeclaration):
        members = decls.structs.setdefault(str(declaration.name), {})
        for element in declaration.declarations:
            for var in element.variables:
                members[str(var.variable.name)] = _type_text(element.init)
    elif isinstance(declaration, EnumeratedTypeDeclaration):
        spec = declaration.init.spec
        values = {str(v.name): _integer(str(v.value)) for v in spec.values}
        decls.enums[str(declaration.name)] = (str(spec.type_name), values)


def _bound(text: str, decls: Declarations) -> int:
    return decls.constants[text] if text in decls.constants else _integer(text)


def _declared_type(decls: Declarations, symbol_name: str) -> str:
    """Follow "GVL.var[i].member..." through the declarations to the leaf's declared type."""
    gvl, *parts = symbol_name.split(".")
    scope = decls.globals[gvl]
    type_text = ""
    for part in parts:
        name, index = re.fullmatch(r"(\w+)(?:\[(\d+)\])?", part).groups()
        type_text = scope[name]
        if index is not None:
            low, high, type_text = _ARRAY.fullmatch(type_text).groups()
            assert _bound(low, decls) <= int(index) <= _bound(high, decls), symbol_name
        scope = decls.structs.get(type_text, {})
    return type_text


def _contract_type(decls: Declarations, declared: str) -> str:
    """The declared type as the contract writes it: enums by base type, arrays as (0..n-1, elem)."""
    array = _ARRAY.fullmatch(declared)
    if array:
        low, high, element = array.groups()
        return f"{element}[{_bound(low, decls)}..{_bound(high, decls)}]"
    if declared in decls.enums:
        return decls.enums[declared][0]
    return declared


def _expected_type(symbol: plc_contract.Symbol) -> str:
    if symbol.array_length is None:
        return symbol.iec_type
    return f"{symbol.iec_type}[0..{symbol.array_length - 1}]"


@pytest.fixture(scope="module")
def decls() -> Declarations:
    return _collect(ST_FILES)


def test_the_plc_sources_are_there():
    names = {p.name for p in ST_FILES}
    assert {"GVL_Axiscal.st", "FB_AxiscalAxis.st", "E_AxiscalCommand.st"} <= names


@pytest.mark.machine
@pytest.mark.parametrize("path", ST_FILES, ids=[p.name for p in ST_FILES])
def test_st_file_parses_with_blark(path):
    parse_st(path)


def _all_symbols(n: int) -> list[plc_contract.Symbol]:
    groups = (plc_contract.control_symbols(n), plc_contract.status_symbols(n), plc_contract.comp_symbols(n))
    return [s for group in groups for s in group.values()]


@pytest.mark.parametrize("n", range(1, plc_contract.MAX_AXES + 1))
def test_every_contract_symbol_is_declared_with_its_type(decls, n):
    for symbol in _all_symbols(n):
        declared = _declared_type(decls, symbol.name)
        assert _contract_type(decls, declared) == _expected_type(symbol), symbol.name


def test_the_gvl_has_room_for_exactly_max_axes(decls):
    for array in ("astAxes", "astComp"):
        low, high, _ = _ARRAY.fullmatch(decls.globals[plc_contract.GVL][array]).groups()
        assert (_bound(low, decls), _bound(high, decls)) == (1, plc_contract.MAX_AXES)


@pytest.mark.parametrize(
    ("struct", "symbols"),
    [
        ("ST_AxiscalControl", plc_contract.control_symbols(1)),
        ("ST_AxiscalStatus", plc_contract.status_symbols(1)),
        ("ST_AxiscalComp", plc_contract.comp_symbols(1)),
    ],
)
def test_the_structs_declare_nothing_the_contract_lacks(decls, struct, symbols):
    assert set(decls.structs[struct]) == set(symbols)


def test_command_enum_matches(decls):
    base, values = decls.enums["E_AxiscalCommand"]
    assert base == "INT"
    assert values == {c.name: c.value for c in plc_contract.Command}


def test_error_id_constants_match(decls):
    for name, error_id in plc_contract.ERROR_ID_CONSTANTS.items():
        assert decls.constants[f"{plc_contract.GVL}.{name}"] == error_id, name
