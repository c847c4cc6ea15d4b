"""YAML read with bounds (penaltyrun.yamlsafe): size, nesting, alias expansion."""

import time

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf._utils import get_yaml_loader

from penaltyrun import yamlsafe
from penaltyrun.yamlsafe import MAX_ALIAS_VALUES, MAX_BYTES, MAX_DEPTH, YamlLimitError


def laughs(levels: int, fan: int = 10) -> str:
    """The "billion laughs": level i is a list of ``fan`` aliases of level i-1."""
    lines = [f"l0: &l0 [{', '.join(['lol'] * fan)}]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * fan)}]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


def test_a_billion_laughs_is_refused_at_once():
    start = time.perf_counter()
    with pytest.raises(YamlLimitError, match=f"bomb.yaml: aliases expand to more than "
                                             f"{MAX_ALIAS_VALUES} values"):
        yamlsafe.load_text(laughs(9), "bomb.yaml")  # 10**9 values
    assert time.perf_counter() - start < 1.0


def test_aliases_within_the_limit_are_read_as_safe_load_reads_them():
    text = laughs(4)  # 10**4 values
    assert yamlsafe.load_text(text) == yaml.safe_load(text)


@pytest.mark.parametrize("text", ["[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1),
                                  "[" * 5000 + "]" * 5000,
                                  "".join(f"{' ' * 2 * i}k{i}:\n" for i in range(200))
                                  + " " * 400 + "v: 1\n"])
def test_deep_nesting_is_refused_before_python_recursion(text):
    with pytest.raises(YamlLimitError, match=f"deep.yaml: nesting deeper than {MAX_DEPTH} "
                                             "levels"):
        yamlsafe.load_text(text, "deep.yaml")


def test_nesting_at_the_limit_is_read():
    depth = MAX_DEPTH - 1  # lists around one scalar: MAX_DEPTH levels of nodes
    data = yamlsafe.load_text("[" * depth + "1" + "]" * depth)
    for _ in range(depth):
        data = data[0]
    assert data == 1


def test_depth_counts_aliases_expanded():
    half = MAX_DEPTH // 2 + 2
    text = f"a: &a {'[' * half}1{']' * half}\nb: {'[' * half}*a{']' * half}\n"
    with pytest.raises(YamlLimitError, match="counted with aliases expanded"):
        yamlsafe.load_text(text, "f.yaml")


def test_a_recursive_alias_is_refused():
    with pytest.raises(YamlLimitError, match="refers to a node that contains it"):
        yamlsafe.load_text("a: &a [1, *a]\n", "f.yaml")


def test_a_file_larger_than_the_limit_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "big.yaml"
    path.write_text("a: [" + "1," * (MAX_BYTES // 2) + "1]\n")
    with pytest.raises(YamlLimitError, match=f"big.yaml: larger than {MAX_BYTES} bytes"):
        yamlsafe.load_file(path)
    with pytest.raises(YamlLimitError, match=f"larger than {MAX_BYTES} bytes"):
        yamlsafe.load_text(path.read_text(), "text")


def test_a_loader_keeps_its_own_resolvers_and_unsafe_tags_stay_refused(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("x: 1e-8\n")
    assert yamlsafe.load_file(path, loader=get_yaml_loader()) == {"x": 1e-8}
    assert yamlsafe.load_file(path) == {"x": "1e-8"}  # YAML 1.1, as yaml.safe_load
    with pytest.raises(yaml.YAMLError):
        yamlsafe.load_text("x: !!python/object/apply:os.system ['true']\n")
    with pytest.raises(TypeError):
        yamlsafe.load_text("x: 1", loader=yaml.UnsafeLoader)


_leaf = st.one_of(st.integers(), st.text(max_size=5), st.booleans(), st.none())
_data = st.recursive(_leaf, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=4), inner, max_size=4)),
    max_leaves=30)


@settings(max_examples=60, deadline=None)
@given(_data)
def test_data_within_the_limits_reads_as_safe_load(data):
    text = yaml.safe_dump(data)
    assert yamlsafe.load_text(text) == yaml.safe_load(text)


def test_interpolations_nested_too_deep_are_refused_before_anything_resolves_them():
    deep = "t_max: " + "${" * 400 + "x" + "}" * 400 + "\n"
    with pytest.raises(yamlsafe.YamlLimitError, match="interpolations .* nested deeper"):
        yamlsafe.load_text(deep, "evil.yaml")
    fine = "a: ${x}\nb: ${oc.env:HOME,${c:${d}}} and ${e}\n"
    assert yamlsafe.load_text(fine)["b"].startswith("${oc.env")
