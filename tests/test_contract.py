"""mimarble/contract.py: the numbers both renderers share are declared there only."""

import ast
import sys
from pathlib import Path

import mimarble.contract as contract

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "mimarble"


def _constant_value(node):
    """The value of a literal expression (numbers, tuples of strings, 2.0 ** -23,
    float(2 ** 24)), else None."""
    if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "float" and len(node.args) == 1:
        node = node.args[0]
    try:
        return ast.literal_eval(node)
    except ValueError:
        pass
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
        base, power = _constant_value(node.left), _constant_value(node.right)
        if isinstance(base, (int, float)) and isinstance(power, (int, float)):
            return base ** power
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        value = _constant_value(node.operand)
        return -value if isinstance(value, (int, float)) else None
    return None


def test_contract_imports_only_the_standard_library():
    tree = ast.parse((PACKAGE / "contract.py").read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            assert not node.level, "contract.py imports from the package"
            names = [node.module]
        else:
            continue
        for name in names:
            assert name.split(".")[0] in sys.stdlib_module_names | {"__future__"}, name


def test_every_contract_name_is_exported():
    public = {n for n in vars(contract) if n.isupper()}
    assert public == set(contract.__all__)


def test_no_module_writes_a_contract_value_again():
    """A module-level literal with a contract value, under a name that says it is that
    fact (the shared word of the two names), is a copy: it must read the contract."""
    shared = {name: getattr(contract, name) for name in contract.__all__}
    copies = []
    for path in PACKAGE.rglob("*.py"):
        if path.name == "contract.py":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if not isinstance(node, (ast.Assign, ast.AnnAssign)) or node.value is None:
                continue
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            value = _constant_value(node.value)
            if value is None or isinstance(value, bool):
                continue
            for target in targets:
                name = getattr(target, "id", "")
                for fact, fact_value in shared.items():
                    if value == fact_value and type(value) is type(fact_value) and (
                            name.strip("_") == fact or name.strip("_").endswith(fact.split("_")[-1])):
                        copies.append(f"{path.relative_to(ROOT)}: {name} = {fact}")
    assert not copies, "read these from mimarble.contract:\n" + "\n".join(copies)


def test_no_module_lists_the_render_modes_again():
    written = repr(contract.RENDER_MODES)
    for path in [*PACKAGE.rglob("*.py"), *(ROOT / "scripts").glob("*.py")]:
        if path.name != "contract.py":
            assert written not in path.read_text(encoding="utf-8"), path


def test_the_former_homes_still_export_the_names():
    from mimarble import parameters, reference
    from mimarble.reference import noise as reference_noise, volume
    from mimarble.scene import limits
    assert reference.EPS_REL is contract.EPS_REL and reference.T_MIN_REL is contract.T_MIN_REL
    assert limits.FLT_MAX is contract.FLT_MAX and limits.FLT_MIN_NORMAL is contract.FLT_MIN_NORMAL
    assert parameters.MAX_OCTAVES == reference_noise.MAX_OCTAVES == contract.MAX_OCTAVES
    assert reference_noise.NOISE_BOUND == contract.NOISE_BOUND
    assert volume.MAX_DEPTH == contract.VOLPATH_MAX_DEPTH
