"""The contact-law registry: what a law file declares is what files, checkpoints and the
loops' dispatch see, and a law that breaks the contract is refused at registration."""

import math

import numpy as np
import pytest

import dem
from dem.contact import laws
from dem.contact.laws import LAWS, Law, register
from dem.contact.laws import dispatch
from dem.io.materials import WALL_KEYS
from dem.io.scene import SCHEMA


def _python(fn):
    """A kernel's Python function: what runs under NUMBA_DISABLE_JIT, reading the slots
    as they are now (a compiled kernel keeps those of its compile)."""
    return getattr(fn, "py_func", fn)


apply_law = _python(dispatch.apply_law)
normal_stiffness = _python(dispatch.normal_stiffness)
row_size = _python(dispatch.row_size)


def test_the_registry_holds_the_built_in_laws_in_code_order():
    assert list(LAWS) == ["linear", "hertz_mindlin", "hertz_sjkr"]
    assert [cls.code for cls in LAWS.values()] == [0, 1, 2]
    assert LAWS["linear"] is dem.LinearSpring and LAWS["hertz_mindlin"] is dem.HertzMindlin
    assert LAWS["hertz_sjkr"] is laws.HertzSJKR


def test_scene_schema_and_wall_keys_come_from_the_laws():
    keys = SCHEMA["contact"].keys
    assert keys["law"].choices == tuple(LAWS)
    for name, cls in LAWS.items():
        for key in cls.keys():
            assert name in keys[key].only, key
        assert set(cls.wall_keys()) <= set(WALL_KEYS[name])
    assert keys["kn"].unit == "N/m" and keys["young"].unit == "Pa"
    # Hertz-Mindlin's keys mean the same in the cohesive law: they are shared
    assert keys["young"].only == ("hertz_mindlin", "hertz_sjkr")
    assert keys["cohesion"].only == ("hertz_sjkr",) and keys["cohesion"].unit == "J/m^3"


@pytest.mark.parametrize("law", [
    dem.LinearSpring(kn=1e5, kt=4e4, mu=0.3, gamma_n=2.0, restitution=0.7),
    dem.HertzMindlin(young=(7e7, math.inf), poisson=0.25, restitution=0.5, mu=0.4,
                     limit_damping=True),
    laws.HertzSJKR(young=7e7, poisson=0.25, restitution=0.5, mu=0.4, cohesion=2e5),
], ids=["linear", "hertz_mindlin", "hertz_sjkr"])
def test_python_dispatch_is_the_laws_own_kernel(law):
    """The dispatch functions called from Python (as with NUMBA_DISABLE_JIT) reach the
    law's kernels, with its row length."""
    p = law.row()[None, None, :]
    assert row_size(law.code) == law.n_params == p.shape[2]
    h1, h2 = np.zeros((1, law.n_hist)), np.zeros((1, law.n_hist))
    args = (1e-4, 1.0, 0.0, 0.0, -0.1, 0.05, 0.0, 5e-3, 0.01, p, 0, 0)
    f = apply_law(law.code, *args, h1, 0, 1e-5)
    g = _python(law.force)(*args, h2, 0, 1e-5)
    assert f == g and np.array_equal(h1, h2)
    assert normal_stiffness(law.code, 1e-4, 5e-3, p, 0, 0) == _python(law.normal_stiffness)(
        1e-4, 5e-3, p, 0, 0)


def test_a_table_builds_the_law_its_file_names():
    table = {"law": "hertz_mindlin", "young": 7e7, "poisson": 0.3, "mu": 0.4,
             "restitution": 0.6, "limit_damping": False}
    wall = {"rigid": True, "mu": 0.2}
    law = laws.law_class("hertz_mindlin").from_table(table, wall, rolling={"mu_roll": 0.1})
    ref = dem.HertzMindlin(young=(7e7, math.inf), poisson=0.3, restitution=0.6, mu=0.2,
                           rolling={"mu_roll": 0.1})
    assert law.spec() == ref.spec()
    assert laws.law_from_spec(law.spec()).spec() == ref.spec()
    with pytest.raises(ValueError, match="unknown contact law 'glue'; known: linear, "
                                         "hertz_mindlin, hertz_sjkr"):
        laws.law_class("glue")


def test_a_row_that_differs_from_n_params_is_refused():
    """The kernels index a contact's parameters by the class's n_params: a row of
    another length is refused when the model builds its table."""

    class Short(dem.LinearSpring):
        n_params = 6

    model = dem.ContactModel(Short(kn=1e5, kt=4e4, mu=0.3))
    with pytest.raises(TypeError, match=r"Short.row\(\) gives 7 numbers, but the class "
                                        r"states n_params = 6"):
        model.table("pp", 1)
    assert dem.ContactModel(dem.LinearSpring(kn=1e5, kt=4e4, mu=0.3)).table(
        "pp", 1).shape == (1, 1, 7)


class _Toy(Law):
    """A law that only exists here: a linear spring with no friction."""

    name = "toy"
    code = 7
    n_params = 1
    n_hist = 0
    force = staticmethod(laws.law_linear)
    stiffness = staticmethod(laws.stiffness_linear)
    energy = staticmethod(laws.energy_linear)
    normal_stiffness = staticmethod(laws.linear.normal_stiffness_linear)

    @classmethod
    def keys(cls):
        return {"kn": dem.LinearSpring.keys()["kn"]}


@pytest.fixture
def toy_registered():
    register(_Toy)
    yield _Toy
    laws.unregister(_Toy.name)


def test_a_new_law_joins_the_schema_in_code_order(toy_registered):
    assert list(LAWS) == ["linear", "hertz_mindlin", "hertz_sjkr", "toy"]
    keys = laws.contact_keys()
    assert keys["law"].choices == ("linear", "hertz_mindlin", "hertz_sjkr", "toy")
    # a key two laws share, with the same meaning, belongs to both
    assert keys["kn"].only == ("linear", "toy")


def test_two_laws_cannot_give_one_key_two_meanings(toy_registered, monkeypatch):
    other = dem.io.schema.Key("float", "N/m^1.5", doc="Normal stiffness.")
    monkeypatch.setattr(_Toy, "keys", classmethod(lambda cls: {"kn": other}))
    with pytest.raises(ValueError, match="contact law toy: key kn differs from another "
                                         "law's kn"):
        laws.contact_keys()


def test_a_law_that_breaks_the_contract_is_refused(toy_registered):
    def variant(**attrs):
        return type("Bad", (_Toy,), attrs)

    with pytest.raises(ValueError, match="named 'toy' is registered already"):
        register(variant())
    with pytest.raises(ValueError, match=r"code must be an integer >= 0 that no other law "
                                         r"has \(taken: .*'LinearSpring'"):
        register(variant(name="toy2", code=0))
    with pytest.raises(ValueError, match=r"code must be an integer >= 0"):
        register(variant(name="toy4", code=-1))
    with pytest.raises(ValueError, match="no energy kernel"):
        register(variant(name="toy3", code=6, energy=None))
    with pytest.raises(ValueError, match="name must be an identifier"):
        register(variant(name="two words", code=9))
    assert list(LAWS) == ["linear", "hertz_mindlin", "hertz_sjkr", "toy"]


def test_a_law_registered_after_the_build_is_refused_by_the_model(toy_registered):
    """The compiled dispatch is written once, for the laws of dem/contact/laws/: a law
    registered later is in the schema but cannot run, and says why."""
    assert _Toy.code not in dispatch.BUILT and dispatch.BUILT == (0, 1, 2)
    with pytest.raises(ValueError, match="contact law 'toy' was registered after "
                                         "dem.contact.laws was loaded"):
        dem.ContactModel(_Toy())
    assert math.isnan(normal_stiffness(_Toy.code, 1e-4, 5e-3, np.ones((1, 1, 1)), 0, 0))
    assert row_size(_Toy.code) == 0


def test_a_history_row_is_the_widest_laws_own_then_rolling():
    plain = dem.ContactModel(dem.LinearSpring(kn=1e5))
    rolling = dem.ContactModel(dem.LinearSpring(kn=1e5, rolling={"mu_roll": 0.1}))
    assert plain.n_hist == 3 and rolling.n_hist == 3 + 7
    assert dem.contact.rolling.COL_ROLL == -7  # counted from the row's end
