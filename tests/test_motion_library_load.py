"""MotionLibrary.load refuses malformed files with a RepertoireError naming the file and the
problem; tuple context values find the same primitives before a save and after a load."""

import json
import re

import numpy as np
import pytest
from repertoire.planning.arm_library import arm_motion_library
from repertoire.planning.motion_library import MotionLibrary, MotionPrimitive

from repertoire.errors import RepertoireError


@pytest.fixture(scope="module")
def grasp_dmp():
    return arm_motion_library().get("grasp_arm7").dmp


def _load(tmp_path, text: str):
    path = tmp_path / "bad.json"
    path.write_text(text)
    return path, lambda: MotionLibrary.load(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[]", "{path} is not a MotionLibrary file: expected a JSON object, got list"),
        ('{"type": "Other"}', "{path} is not a MotionLibrary file: 'type' is 'Other'"),
        ('{"type": "MotionLibrary"}', "{path}: MotionLibrary file has no 'primitives' key"),
        (
            '{"type": "MotionLibrary", "primitives": {}}',
            "{path}: 'primitives' must be a list, got dict",
        ),
        (
            '{"type": "MotionLibrary", "primitives": [3]}',
            "{path}: primitives[0] must be a JSON object, got int",
        ),
        (
            '{"type": "MotionLibrary", "primitives": [{"name": "x"}]}',
            "{path}: primitives[0] is missing keys 'label', 'dmp'",
        ),
        (
            '{"type": "MotionLibrary", "primitives": [{"name": "x", "dmp": {}}]}',
            "{path}: primitives[0] is missing key 'label'",
        ),
        (
            '{"type": "MotionLibrary", "primitives": '
            '[{"name": "x", "label": "grasp", "dmp": {}, "context": [1]}]}',
            "{path}: primitives[0]: 'context' must be a JSON object, got list",
        ),
        (
            '{"type": "MotionLibrary", "primitives": [{"name": "x", "label": "grasp", "dmp": {}}]}',
            "{path}: primitives[0] ('x') is malformed: unknown DMP artefact type None",
        ),
        (
            '{"type": "MotionLibrary", "primitives": '
            '[{"name": "x", "label": "grasp", "dmp": {"type": "TaskSpaceDmp"}}]}',
            "{path}: primitives[0] ('x') is malformed: missing key 'position'",
        ),
        ("not json", "cannot read a motion library from {path}: Expecting value"),
    ],
)
def test_malformed_files_are_refused_naming_file_and_problem(tmp_path, text, message):
    path, load = _load(tmp_path, text)
    with pytest.raises(RepertoireError, match=re.escape(message.format(path=path))):
        load()


def test_bad_primitive_in_a_file_names_the_file(tmp_path, grasp_dmp):
    record = MotionPrimitive("x", "grasp", grasp_dmp).to_dict()
    record["label"] = "juggle"
    path, load = _load(tmp_path, json.dumps({"type": "MotionLibrary", "primitives": [record]}))
    with pytest.raises(RepertoireError, match=re.escape(f"{path}: primitives[0] ('x')")):
        load()
    path, load = _load(
        tmp_path,
        json.dumps({"type": "MotionLibrary", "primitives": [record | {"label": "grasp"}] * 2}),
    )
    with pytest.raises(
        RepertoireError, match=re.escape(f"{path}: the library already has a primitive named 'x'")
    ):
        load()


def test_missing_file_is_a_repertoire_error(tmp_path):
    with pytest.raises(RepertoireError, match="cannot read a motion library from .*nope.json"):
        MotionLibrary.load(tmp_path / "nope.json")


def test_tuple_context_finds_the_same_before_save_and_after_load(tmp_path, grasp_dmp):
    lib = MotionLibrary()
    lib.add_dmp("a", "grasp", grasp_dmp, {"side": (1, 2), "nested": {"p": (0.5, (1, 2))}})
    lib.add_dmp("b", "grasp", grasp_dmp, {"side": [3, 4]})
    assert lib.get("a").context == {"side": [1, 2], "nested": {"p": [0.5, [1, 2]]}}
    loaded = MotionLibrary.load(lib.save(tmp_path / "lib.json"))
    for library in (lib, loaded):
        assert [p.name for p in library.find("grasp", side=(1, 2))] == ["a"]
        assert [p.name for p in library.find("grasp", side=[1, 2])] == ["a"]
        assert [p.name for p in library.find("grasp", side=(3, 4))] == ["b"]
        assert [p.name for p in library.find("grasp", nested={"p": (0.5, [1, 2])})] == ["a"]
        assert library.find("grasp", side=(2, 1)) == []
        assert library.select("grasp", side=(3, 4)).name == "b"
    assert loaded.get("a").context == lib.get("a").context


def test_non_json_context_is_refused(grasp_dmp):
    with pytest.raises(RepertoireError, match="context of 'a' must hold only JSON values"):
        MotionPrimitive("a", "grasp", grasp_dmp, {"side": {1, 2}})
    with pytest.raises(RepertoireError, match="context of 'a' must be a dict, got list"):
        MotionPrimitive("a", "grasp", grasp_dmp, [("side", 1)])


@pytest.mark.parametrize("value", [float("nan"), float("inf"), np.float64("-inf"), [1.0, np.nan]])
def test_non_finite_context_numbers_are_refused(tmp_path, grasp_dmp, value):
    """JSON has no NaN or infinity: a library saved with one was written with a bare ``NaN``
    (which other JSON readers reject), and ``find`` never matched it."""
    with pytest.raises(
        RepertoireError,
        match=re.escape("context of 'a' must hold only JSON values: Out of range float values"),
    ):
        MotionPrimitive("a", "grasp", grasp_dmp, {"width": value})


def test_numpy_context_values_are_stored_and_found_as_json(tmp_path, grasp_dmp):
    # NumPy arrays and scalars (what a scenario computes) are their JSON lists and numbers;
    # a find() with an array used to raise NumPy's "truth value of an array is ambiguous"
    lib = MotionLibrary()
    lib.add_dmp("a", "grasp", grasp_dmp, {"cup_xy": np.array([0.5, -0.2]), "n": np.int64(3)})
    lib.add_dmp("b", "grasp", grasp_dmp, {"cup_xy": [0.1, 0.2], "n": 3.5})
    assert lib.get("a").context == {"cup_xy": [0.5, -0.2], "n": 3}
    assert type(lib.get("a").context["n"]) is int
    loaded = MotionLibrary.load(lib.save(tmp_path / "lib.json"))
    for library in (lib, loaded):
        assert [p.name for p in library.find("grasp", cup_xy=np.array([0.5, -0.2]))] == ["a"]
        assert [p.name for p in library.find("grasp", cup_xy=np.array([0.1, 0.2]))] == ["b"]
        assert [p.name for p in library.find("grasp", n=np.float64(3.5))] == ["b"]
        assert library.find("grasp", cup_xy=np.array([[0.5, -0.2]])) == []


@pytest.fixture
def two_primitive_library(grasp_dmp):
    lib = MotionLibrary()
    lib.add_dmp("a", "grasp", grasp_dmp, {"object": "cup"})
    lib.add_dmp("b", "place", grasp_dmp.position)
    return lib


def test_save_writes_format_version_1_and_round_trips(tmp_path, two_primitive_library):
    lib = two_primitive_library
    path = lib.save(tmp_path / "lib.json")
    written = json.loads(path.read_text())
    assert list(written) == ["type", "format_version", "primitives"]
    assert written["format_version"] == 1
    loaded = MotionLibrary.load(path)
    assert json.dumps(loaded.to_dict()) == json.dumps(lib.to_dict())
    np.testing.assert_array_equal(loaded.get("b").dmp.weights, lib.get("b").dmp.weights)


def test_a_file_without_format_version_is_read_as_version_1(tmp_path, two_primitive_library):
    lib = two_primitive_library
    old = lib.to_dict()
    del old["format_version"]  # the layout files had before the field
    path = tmp_path / "old.json"
    path.write_text(json.dumps(old, indent=1))
    loaded = MotionLibrary.load(path)
    assert json.dumps(loaded.to_dict()) == json.dumps(lib.to_dict())
    assert [p.name for p in loaded] == ["a", "b"]
    assert loaded.get("a").context == {"object": "cup"}
    assert loaded.get("b").dmp.tau == lib.get("b").dmp.tau


@pytest.mark.parametrize("version", [2, 0, "1", 1.0, True, None])
def test_an_unknown_format_version_is_refused_naming_it(tmp_path, version):
    text = json.dumps({"type": "MotionLibrary", "format_version": version, "primitives": []})
    path, load = _load(tmp_path, text)
    message = f"{path} has motion library format version {version!r}; this code reads versions 1"
    with pytest.raises(RepertoireError, match=re.escape(message)):
        load()


@pytest.mark.parametrize("name", ["lib.npz", "lib", "lib.JSON", "lib.json.txt"])
def test_save_refuses_a_suffix_other_than_json(tmp_path, two_primitive_library, name):
    path = tmp_path / name
    suffix = repr(path.suffix) if path.suffix else "'no suffix'"
    message = f"a motion library is saved as JSON: {path} must end in '.json', not {suffix}"
    with pytest.raises(RepertoireError, match=re.escape(message)):
        two_primitive_library.save(path)
    assert not path.exists()


def test_load_reads_json_content_under_another_name(tmp_path, two_primitive_library):
    # files the old save wrote under e.g. ".npz" (JSON inside) still load as before
    path = tmp_path / "old.npz"
    path.write_text(json.dumps(two_primitive_library.to_dict()))
    loaded = MotionLibrary.load(path)
    assert json.dumps(loaded.to_dict()) == json.dumps(two_primitive_library.to_dict())


@pytest.mark.parametrize(
    ("part", "field", "value", "problem"),
    [
        ("position", "tau", "1.0", "tau must be a number, got '1.0'"),
        ("position", "alpha", True, "alpha must be a number, got True"),
        ("orientation", "tau", "1.0", "tau must be a number, got '1.0'"),
        ("orientation", "K", "150", "K must be a number, got '150'"),
        ("position", "K", ["1", "2", "3"], "K must be a number or one number per DOF (3), got"),
        ("position", "goal", [0.1, "0.2", 0.3], "goal must be numbers, got [0.1, '0.2', 0.3]"),
        ("position", "x0", [0.1, None, 0.3], "x0 must be numbers, got [0.1, None, 0.3]"),
    ],
)
def test_non_numeric_dmp_fields_are_refused_naming_the_field(
    tmp_path, grasp_dmp, part, field, value, problem
):
    record = MotionPrimitive("x", "grasp", grasp_dmp).to_dict()
    record["dmp"][part][field] = value
    text = json.dumps({"type": "MotionLibrary", "format_version": 1, "primitives": [record]})
    path, load = _load(tmp_path, text)
    with pytest.raises(
        RepertoireError, match=re.escape(f"{path}: primitives[0] ('x') is malformed: {problem}")
    ):
        load()


def test_misspelt_keys_are_refused_naming_them(tmp_path, grasp_dmp):
    """A misspelt optional key was dropped without a word (the context, the fingers, the
    format version), so the file loaded as another library."""
    record = MotionPrimitive("x", "grasp", grasp_dmp, {"object": "cup"}).to_dict()
    record["contxt"] = record.pop("context")
    path, load = _load(tmp_path, json.dumps({"type": "MotionLibrary", "primitives": [record]}))
    with pytest.raises(
        RepertoireError,
        match=re.escape(
            f"{path}: primitives[0] has unknown keys ['contxt']; expected only ['name', "
            "'label', 'dmp', 'context']"
        ),
    ):
        load()
    record["context"] = record.pop("contxt")
    text = json.dumps({"type": "MotionLibrary", "format_versoin": 2, "primitives": [record]})
    path, load = _load(tmp_path, text)
    with pytest.raises(
        RepertoireError,
        match=re.escape(f"{path}: MotionLibrary file has unknown keys ['format_versoin']"),
    ):
        load()
    record["dmp"]["finger"] = record["dmp"].pop("fingers")
    path, load = _load(tmp_path, json.dumps({"type": "MotionLibrary", "primitives": [record]}))
    with pytest.raises(
        RepertoireError,
        match=re.escape(
            f"{path}: primitives[0] ('x') is malformed: TaskSpaceDmp record has unknown keys "
            "['finger']; expected only ['type', 'position', 'orientation', 'fingers']"
        ),
    ):
        load()
