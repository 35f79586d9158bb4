"""Scene files: validation errors name the key and the line; settings override."""

from pathlib import Path

import pytest

from skfem_rkpm.runs.runner import build
from skfem_rkpm.runs.scene import (SCHEMA, SceneError, apply_setting, builtin_scenes,
                              load_scene, parse_scene, schema_markdown)

GOOD = """
[model]
type = "plane_strain"

[geometry]
x = [0.0, 1.0]
y = [0.0, 1.0]
divisions = [4, 4]

[material]
E = 200e3
nu = 0.3
yield = 300.0

[boundary.bottom]
fix = ["y"]
"""


def error_of(text):
    with pytest.raises(SceneError) as info:
        parse_scene(text, "block.toml")
    return str(info.value)


def test_good_scene_fills_defaults():
    scene = parse_scene(GOOD, "block.toml")
    assert scene["model"]["method"] == "rkpm"
    assert scene["discretization"]["dilation"] == 2.0
    assert scene["boundary.bottom"]["method"] == "nodal"
    assert scene["material"]["E"] == 200e3 and isinstance(scene["material"]["yield"], float)


@pytest.mark.parametrize("edit, expected", [
    (("nu = 0.3", "nu = 0.5"), "block.toml, line 12: material.nu: must lie in (-1, 0.5)"),
    (("E = 200e3", "E = -1.0"), "block.toml, line 11: material.E: must be positive"),
    (("E = 200e3", 'E = "steel"'), "line 11: material.E: must be of type float"),
    (("yield = 300.0", "yeld = 300.0"), "line 13: material.yeld: unknown key"),
    (('type = "plane_strain"', 'type = "plane_stress"'),
     "line 3: model.type: must be one of ['plane_strain', 'axisymmetric', '3d']"),
    (('fix = ["y"]', 'fix = ["w"]'), "line 16: boundary.bottom.fix: unknown component 'w'"),
    (("divisions = [4, 4]", "divisions = [4]"), "line 8: geometry.divisions: needs two values"),
    (("[geometry]", "[geometri]"), "line 5: geometri: unknown section"),
    (("E = 200e3\n", ""), "material: missing required key 'E'"),
])
def test_errors_name_key_and_line(edit, expected):
    assert expected in error_of(GOOD.replace(*edit))


def test_missing_material_section_and_bad_toml():
    assert "missing required section [material]" in error_of(
        GOOD.split("[material]")[0])
    assert "not valid TOML" in error_of(GOOD + "\nE = \n")


def test_support_too_small_is_reported_with_the_dilation_that_works():
    from skfem_rkpm.runs.runner import build
    from skfem_rkpm.approximation.shape import SingularMomentError

    scene = parse_scene(GOOD + "\n[discretization]\ndilation = 0.6\n", "block.toml")
    with pytest.raises(SingularMomentError, match="smallest normalized support"):
        build(scene)


def test_support_radius_too_small_is_reported_as_a_growth_factor():
    """With ``discretization.support`` (a radius, not a multiple of the
    spacing) the message gives the factor the radius must grow by instead
    of a normalized support the scene does not use."""
    from skfem_rkpm.runs.runner import build
    from skfem_rkpm.approximation.shape import SingularMomentError

    scene = parse_scene(GOOD + "\n[discretization]\nsupport = 0.05\n", "block.toml")
    with pytest.raises(SingularMomentError, match="Supports must grow by a factor of at "
                                                  "least") as err:
        build(scene)
    assert "normalized support" not in str(err.value)


def test_settings_override_and_add_keys():
    text = apply_setting(GOOD, "material.nu=0.25")
    assert parse_scene(text)["material"]["nu"] == 0.25
    text = apply_setting(GOOD, "tools.platen.friction=stick")
    text = apply_setting(text, "tools.platen.point=[0.0, 1.0]")
    text = apply_setting(text, "tools.platen.normal=[0.0, -1.0]")
    scene = parse_scene(text)
    assert scene["tools.platen"]["friction"] == "stick"
    assert scene["tools.platen"]["point"] == [0.0, 1.0]
    with pytest.raises(SceneError, match="expected key=value"):
        apply_setting(GOOD, "material.nu")


def test_every_key_is_documented():
    table = schema_markdown()
    for section, keys in SCHEMA.items():
        for key in keys:
            assert f"| `{key}` |" in table
    with open(Path(__file__).parent.parent / "docs" / "scenes.md") as handle:
        assert table in handle.read(), "regenerate docs/scenes.md from schema_markdown()"


def test_builtin_scenes_are_valid():
    scenes = builtin_scenes()
    assert "ring" in scenes
    for path in scenes.values():
        load_scene(path)


def test_tool_slave_boundary_missing_from_the_mesh_names_the_tool():
    scene = load_scene(builtin_scenes()["ring"],
                       ['tools.platen.slaves=["top", "nose"]', "geometry.divisions=[4,3]"])
    with pytest.raises(SceneError, match=r"\[tools.platen\] slaves: the mesh has no "
                       r"boundary 'nose'; it has \['bottom', 'left', 'right', 'top'\]"):
        build(scene, "fem")


@pytest.mark.parametrize("setting, message", [
    # once appended at the end of the file: "line 50 of a 49-line file", filed
    # under [output]
    ("foo=1", "--set 'foo=1': unknown key 'foo': give SECTION.KEY"),
    ("model.foo=1", "--set 'model.foo=1': unknown key 'model.foo'; known keys of "
                    "[model]: force_unit, length_unit, method, title, type"),
    ("solver.tolerance=1", "unknown section 'solver' in 'solver.tolerance'"),
    ("tools.friction=0.1", "'tools.friction' names no tools: give tools.NAME.KEY, e.g. "
                           "tools.platen.friction"),
    # once inserted a new table into the scene
    ("model.title=a\n[tools.x]\nkind=1", "a value must be one line"),
    ("model.title=a\r\nb", "a value must be one line"),
])
def test_settings_with_unknown_keys_or_line_breaks_are_refused(setting, message):
    ring = builtin_scenes()["ring"]
    with pytest.raises(SceneError) as info:
        load_scene(ring, [setting])
    assert message in str(info.value)
    assert ", line " not in str(info.value)  # no line of the scene file is blamed


def test_settings_for_a_new_tool_or_boundary_add_its_table():
    text = apply_setting(GOOD, "boundary.left.fix=[\"x\"]")
    assert parse_scene(text)["boundary.left"]["fix"] == ["x"]


def test_a_bad_set_value_is_named_by_the_set_a_bad_file_value_by_its_line(tmp_path):
    ring = builtin_scenes()["ring"]
    line = next(n for n, text in enumerate(ring.read_text().splitlines(), start=1)
                if text.startswith("E = "))
    # the value came from --set: quoted as the user wrote it, no line of ring.toml
    with pytest.raises(SceneError) as info:
        load_scene(ring, ["material.E=nan"])
    assert str(info.value) == "--set material.E=nan: must be finite, not nan"
    # a key the file does not have, added by --set (once: the inserted line)
    with pytest.raises(SceneError) as info:
        load_scene(ring, ["discretization.dilation=-2"])
    assert str(info.value).startswith("--set discretization.dilation=-2: must be positive")
    # the last --set of a key is the one used, and the one named
    with pytest.raises(SceneError) as info:
        load_scene(ring, ["material.nu=0.3", "material.nu=0.7"])
    assert str(info.value).startswith("--set material.nu=0.7: must lie in (-1, 0.5)")
    # a combination checked after the values: named by the --set too
    with pytest.raises(SceneError) as info:
        load_scene(ring, ['material.hardening="swift"'])
    assert str(info.value).startswith(
        "--set material.hardening=\"swift\": swift needs 'K', 'n'")
    # the same bad value in the file itself: its file and line, as before
    bad = tmp_path / "ring.toml"
    bad.write_text(ring.read_text().replace("E = 288e3", "E = nan"))
    with pytest.raises(SceneError) as info:
        load_scene(bad, ["steps.count=3"])  # another --set does not take the blame
    assert str(info.value) == f"{bad}, line {line}: material.E: must be finite, not nan"


def test_the_command_line_names_the_set(tmp_path, capsys):
    from skfem_rkpm.runs.cli import main

    assert main(["run", "ring", "--set", "material.E=nan", "--out",
                 str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err == "error: --set material.E=nan: must be finite, not nan\n"
    assert not (tmp_path / "o").exists()
