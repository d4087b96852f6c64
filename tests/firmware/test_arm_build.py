"""Cortex-M0+ cross-build of the cell library: no soft float, no division on the control path, size."""

import shutil
import subprocess
from pathlib import Path

import pytest

from metacell_tools.fwcheck import armbuild

pytestmark = pytest.mark.skipif(
    shutil.which(armbuild.CC) is None, reason="arm-none-eabi-gcc missing (tools/setup.sh installs it)"
)


@pytest.fixture(scope="module")
def lib_objs():
    return armbuild.library_objects()


def compile_snippet(tmp_path: Path, name: str, code: str) -> Path:
    src = tmp_path / f"{name}.c"
    src.write_text(code)
    return armbuild.compile_objects([src], tmp_path / "obj")[0]


def test_every_library_source_is_cross_compiled(lib_objs):
    assert len(lib_objs) == len(armbuild.library_sources()) >= 6
    assert all(o.exists() for o in lib_objs)


def test_library_references_no_soft_float_helper(lib_objs):
    assert armbuild.softfloat_violations(lib_objs) == {}


def test_soft_float_checker_flags_a_float_object(tmp_path, lib_objs):
    bad = compile_snippet(
        tmp_path, "floaty", "float f(float a, int b) { return a * 2.5f + b; }\ndouble g(double x) { return x / 3.0; }\n"
    )
    found = armbuild.softfloat_violations(lib_objs + [bad])
    assert list(found) == ["floaty.o"]
    assert {"__aeabi_fmul", "__aeabi_ddiv"} <= set(found["floaty.o"])


def test_control_path_reaches_no_division_helper(lib_objs):
    rep = armbuild.division_check(lib_objs)
    assert rep.ok, f"division on the control path: {rep.violations}, indirect: {rep.indirect}"
    # the walk really started at every root
    assert set(armbuild.CONTROL_ROOTS) <= set(rep.reachable)
    assert not any(n.startswith("mc_drive_configure") for n in rep.reachable)


def test_division_checker_sees_the_configuration_path_divide(lib_objs):
    rep = armbuild.division_check(lib_objs, ["mc_drive_configure"])
    assert not rep.ok
    assert all(armbuild.DIVISION_RE.match(chain[-1]) for chain in rep.violations)
    assert rep.violations[0][0] == "mc_drive_configure"


BAD_C = """
static int __attribute__((noinline)) helper(int a, int b) { return a / b; }
int ctl(int a, int b) { return helper(a, b) + 1; }
unsigned cfg(unsigned a, unsigned b) { return a % b; }
int clean(int a) { return (a >> 3) + ctl_far(a); }
"""


def test_division_checker_flags_a_bad_object(tmp_path, lib_objs):
    bad = compile_snippet(tmp_path, "bad", "int ctl_far(int a);\n" + BAD_C)
    far = compile_snippet(tmp_path, "far", "int ctl_far(int a) { return a * 7; }\n")
    objs = lib_objs + [bad, far]
    rep = armbuild.division_check(objs, ["ctl"])
    assert rep.violations == [["ctl", "helper", "__aeabi_idiv"]]
    rep = armbuild.division_check(objs, ["cfg"])
    assert rep.violations == [["cfg", "__aeabi_uidivmod"]]
    # reachability, not a blanket ban: a clean root through another object passes
    rep = armbuild.division_check(objs, ["clean", *armbuild.CONTROL_ROOTS])
    assert rep.ok and "ctl_far" in rep.reachable
    # ... and turns bad when the far function starts dividing
    far2 = compile_snippet(tmp_path, "far2", "int ctl_far(int a) { return 1000 / a; }\n")
    rep = armbuild.division_check(lib_objs + [bad, far2], ["clean"])
    assert rep.violations == [["clean", "ctl_far", "__aeabi_idiv"]]


def test_indirect_calls_on_the_control_path_are_reported(tmp_path):
    obj = compile_snippet(tmp_path, "ind", "int ind(int (*f)(int), int x) { return f(x) + 1; }\n")
    rep = armbuild.division_check([obj], ["ind"])
    assert rep.indirect == ["ind"] and not rep.ok


def test_unknown_entry_point_is_an_error(lib_objs):
    with pytest.raises(KeyError, match="no_such_fn"):
        armbuild.division_check(lib_objs, ["no_such_fn"])


def test_code_size_is_reported(lib_objs):
    rows = armbuild.code_size(lib_objs)
    total = rows[-1]
    assert total.name == "total" and len(rows) == len(lib_objs) + 1
    assert total.text == sum(r.text for r in rows[:-1]) > 0
    # cross-check against binutils' own section listing of one object
    out = subprocess.run(
        ["arm-none-eabi-size", "-A", str(lib_objs[0])], capture_output=True, text=True, check=True
    ).stdout
    text = sum(int(ln.split()[1]) for ln in out.splitlines() if ln.startswith((".text", ".rodata")))
    assert rows[0].text >= text
    print("\n" + armbuild.format_size(rows))
