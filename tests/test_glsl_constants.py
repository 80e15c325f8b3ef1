"""No GLSL compares a shared quantity with a bare number (issue 40).

A shared quantity holds one of the host's codes: a parameterization, a layer or light
kind, a mode, a flag or a sentinel (`shaders.CODES` names, beside each table, the uniforms
that carry it). The GLSL compares such a quantity only with the names `SHARED_DEFINES`
gives the codes, so a code changed on the host changes in every shader. The checker
follows a quantity through `#define` aliases, local copies and function arguments.
Pure Python: no GL context.
"""
from __future__ import annotations

import re

from addon.render import shaders as S

_OPERATOR = r"(?:==|!=|<=|>=|<|>)"
_NUMBER = r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?[uUfF]?"
_CAST = r"(?:(?:int|uint|float)\s*\(\s*)?"
_INDEX = r"(?:\s*\[[^\]]*\])?"  # an element of an array that holds codes
_TYPES = r"(?:void|bool|int|uint|float|[iu]?vec[234]|mat[234]|OwLightView|OwBlend)"


def _strip_comments(text: str) -> str:
    return re.sub(r"//[^\n]*", "", re.sub(r"/\*.*?\*/", "", text, flags=re.DOTALL))


def _holder(expression: str) -> str:
    """A regex for `expression` (a name, or name.component) as a whole operand."""
    return rf"(?<![\w.]){re.escape(expression)}(?![\w])"


def _arguments(text: str, start: int) -> list[str]:
    """The top-level, comma-separated arguments of the call whose '(' is at `start`."""
    depth, current, out = 0, [], []
    for char in text[start:]:
        if char == "(":
            depth += 1
            if depth == 1:
                continue
        elif char == ")":
            depth -= 1
            if depth == 0:
                out.append("".join(current).strip())
                return out
        elif char == "," and depth == 1:
            out.append("".join(current).strip())
            current = []
            continue
        current.append(char)
    return out


def _functions(text: str) -> dict[str, list[str]]:
    """Each function defined in `text` -> its parameters' names."""
    found = {}
    for match in re.finditer(rf"\b{_TYPES}\s+(\w+)\s*\(([^()]*)\)\s*\{{", text):
        params = [part.split()[-1].split("[")[0] for part in match.group(2).split(",") if part.strip()]
        found[match.group(1)] = [] if params == ["void"] else params
    return found


def _copies(texts: list[str], known: set[str]) -> set[str]:
    """Names that take over a known quantity: a `#define` alias, a local copy, a parameter."""
    found = set()
    functions = {name: params for text in texts for name, params in _functions(text).items()}
    for text in texts:
        for holder in known:
            pattern = _holder(holder)
            found.update(re.findall(rf"#define\s+(\w+)\s+{pattern}\s*$", text, flags=re.MULTILINE))
            found.update(re.findall(rf"\b(?:int|uint|float)\s+(\w+)\s*=\s*{_CAST}{pattern}{_INDEX}\s*\)?\s*;", text))
        for name, params in functions.items():
            for call in re.finditer(rf"(?<![\w.]){name}\s*\(", text):
                for param, argument in zip(params, _arguments(text, call.end() - 1)):
                    for holder in known:
                        base, _, component = holder.partition(".")
                        if re.fullmatch(rf"{_CAST}{re.escape(holder)}\s*\)?", argument):
                            found.add(param)
                        elif component and argument == base:
                            found.add(f"{param}.{component}")
    return found


def shared_quantities(sources: dict[str, str]) -> set[str]:
    """The GLSL expressions that hold a shared code: `shaders.CODES`'s holders, and every
    name that takes one over in `sources` (file name -> text)."""
    texts = [_strip_comments(text) for text in sources.values()]
    known = {holder for table in S.CODES for holder in table.holders}
    while True:
        more = _copies(texts, known) - known
        if not more:
            return known
        known |= more


def bare_comparisons(sources: dict[str, str]) -> list[str]:
    """'file:line: text' for each comparison of a shared quantity with a bare number."""
    quantities = shared_quantities(sources)
    bad = []
    for name, text in sorted(sources.items()):
        for number, line in enumerate(_strip_comments(text).splitlines(), 1):
            for holder in quantities:
                operand = rf"{_CAST}{_holder(holder)}{_INDEX}\s*\)?"
                if (re.search(rf"{operand}\s*{_OPERATOR}\s*\(?\s*{_NUMBER}(?![\w.])", line)
                        or re.search(rf"(?<![\w.]){_NUMBER}\s*\)?\s*{_OPERATOR}\s*\(?\s*{operand}", line)):
                    bad.append(f"{name}:{number}: {line.strip()}")
                    break
    return bad


def _shader_sources() -> dict[str, str]:
    return {path.relative_to(S.SHADER_DIR).as_posix(): path.read_text(encoding="utf-8")
            for path in sorted(S.SHADER_DIR.rglob("*")) if path.is_file()}


def test_no_shader_compares_a_shared_quantity_with_a_bare_number():
    sources = _shader_sources()
    assert len(sources) > 20
    quantities = shared_quantities(sources)
    # The checker follows the codes into the GLSL's own names (lib/spot_cone.glsl's spot,
    # scatter.comp's OW_MODE, projection.glsl's kind), so it is not blind to copies.
    assert {"spot.x", "OW_MODE", "kind", "extension", "tile"} <= quantities
    assert bare_comparisons(sources) == []


def test_every_code_carrying_uniform_has_its_table():
    """Each uniform that holds a kind, a mode, a pass or a parameterization, and each holder
    a table names, is real: the tables and the interfaces agree."""
    interfaces = (*S.PROGRAMS, *S.COMPUTE_PROGRAMS)
    declared = {uniform.name for iface in interfaces for uniform in iface.uniforms}
    declared |= {name for iface in S.PROGRAMS for _, name in iface.fragment_out}
    holders = {holder for table in S.CODES for holder in table.holders}
    coded = {name for name in declared if re.search(r"_(kind|mode|pass|param)$", name)}
    held = {re.match(r"\w+", holder).group() for holder in holders}
    assert coded <= held, sorted(coded - held)
    defines = {name for iface in interfaces for name in iface.defines} | {S.SCATTER_MODE_DEFINE}
    assert held <= declared | defines, sorted(held - declared - defines)
    for table in S.CODES:
        assert table.defines().items() <= S.SHARED_DEFINES.items()


def test_the_checker_catches_a_planted_comparison():
    planted = """
    #define OW_ALIAS ow_scatter_mode
    float ow_cone(vec2 spot) { return (spot.x < -1.5) ? 1.0 : 0.0; }  // through a parameter
    void main()
    {
      int k = int(ow_exact_light.x);  // through a copy
      if (ow_soft_kind == 2) {}
      if (k != 3) {}
      if (1 == ow_mode) {}
      if (OW_ALIAS >= 1) {}
      float c = ow_cone(ow_soft_spot);
      if (ow_soft_kind == OW_LIGHT_AREA && ow_result.y != OW_FLAG_OUTSIDE) {}  // named: fine
      if (ow_projective != 0) {}  // a yes/no uniform, not a code: fine
    }
    """
    bad = bare_comparisons({"planted.frag": planted})
    assert [entry.split(":")[1] for entry in bad] == ["3", "7", "8", "9", "10"], bad
    # One planted line in an otherwise clean copy of the shipped tree is caught too.
    sources = _shader_sources()
    sources["lib/soft.glsl"] += "\nbool ow_planted() { return ow_soft_kind != 1; }\n"
    assert bare_comparisons(sources) == [f"lib/soft.glsl:{sources['lib/soft.glsl'].count(chr(10))}: "
                                         "bool ow_planted() { return ow_soft_kind != 1; }"]
