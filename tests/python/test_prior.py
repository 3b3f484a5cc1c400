"""Store.write_prior: the same prior as `specula prior build` from the same grids, bit for bit (grids of a store, a
whole store, grids in memory; exclude, components and epsilon), committed with a `with` block, and bad input refused
in one line with the store left as it was."""
import itertools
from pathlib import Path

import h5py
import numpy as np
import pytest

import specula
from conftest import cli

WL = ("--wavelengths", "400:700:300")  # 2 bands, 2 channels: a build takes about a second
MATERIALS = ("blue-paint", "gold", "green-matte")
RUNS = itertools.count()


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    """Three analytic grids on 2 bands, and a store with one grid on 3 bands."""
    d = tmp_path_factory.mktemp("prior")
    path = d / "db.h5"
    for m in MATERIALS:
        cli("synth-brdf", m, *WL, "-o", f"{path}:{m}")
    cli("synth-brdf", "cyan-gloss", "--wavelengths", "400:700:150", "-o", f"{d / 'other.h5'}:cyan-gloss")
    return path


def cli_prior(tmp_path, *args):
    """The store `specula prior build ARGS` writes prior p into, and what it prints."""
    out = tmp_path / f"cli{next(RUNS)}.h5"
    r = cli("prior", "build", *args, "-o", out, "--name", "p")
    return out, r.stdout


@pytest.fixture(scope="module")
def cli_specs(db, tmp_path_factory):
    """`specula prior build` of the three grids named STORE.h5:NAME."""
    return cli_prior(tmp_path_factory.mktemp("cli"), *(f"{db}:{m}" for m in MATERIALS), "--channels", 2)


@pytest.fixture(scope="module")
def cli_whole(db, tmp_path_factory):
    """`specula prior build` of the whole store less green-matte, with components and epsilon."""
    return cli_prior(tmp_path_factory.mktemp("cli"), db, "--exclude", "green-matte", "--channels", 2, "--components",
                     2, "--epsilon", 0.01)


def prior_tables(path, name):
    """Every dataset of prior `name` (raw bytes, dtype, shape) and its attributes but the time and command line."""
    with h5py.File(path, "r") as f:
        g = f["priors"][name]
        data = {k: (g[k].dtype.str, g[k].shape, g[k][...].tobytes()) for k in g}
        attrs = {k: g.attrs[k] for k in g.attrs if k not in ("created_utc", "command_line")}
    return data, attrs


def assert_same_prior(path, name, cli_path, training=True):
    data, attrs = prior_tables(path, name)
    cli_data, cli_attrs = prior_tables(cli_path, "p")
    assert sorted(data) == sorted(cli_data)
    for k in data:
        assert data[k] == cli_data[k], k
    if not training:
        attrs.pop("training"), cli_attrs.pop("training")
    assert attrs == cli_attrs


def test_store_specs_are_the_clis_prior_with_what_it_prints(db, cli_specs, tmp_path):
    specs = [f"{db}:{m}" for m in MATERIALS]
    s = specula.Store(tmp_path / "py.h5", "a")
    r = s.write_prior("p", specs, channels=2)
    cli_path, printed = cli_specs
    assert_same_prior(s.path, "p", cli_path)
    # prior p of OUT: K components over CELLS cells, C channels (...), from N grids in S s; ... rows: P1,P2,...
    head, exponents = printed.strip().rsplit(": ", 1)
    words = head.split(": ", 1)[1].split()
    assert (r["k"], r["cells"], r["channels"]) == (int(words[0]), int(words[3]), int(words[5]))
    np.testing.assert_array_equal(r["retro_exponents"], [float(p) for p in exponents.split(",")])
    assert len(r["retro_exponents"]) == 8 and 0 < r["k"] < len(MATERIALS) * 2 and r["channels"] == 2
    assert len(r["retro_rise"]) == sum(2 * w * w for w in range(1, 9)) and np.all(np.isfinite(r["retro_rise"]))
    np.testing.assert_array_equal(r["wavelengths"], [400, 700])
    assert r["training"] == specs and r["name"] == "p" and r["store"] == s.path
    assert r["knots"].tolist() == [400, 700] and r["epsilon"] == 1e-3 and r["variances"].shape == (r["k"],)
    assert r["seconds"] > 0
    with h5py.File(s.path, "r") as f:
        assert f["priors/p"].attrs["command_line"].startswith("python: specula.Store.write_prior")
        np.testing.assert_array_equal(f["priors/p/retro_rise"][...], r["retro_rise"])
        assert f["priors/p"].attrs["prior_version"] == 4


@pytest.mark.parametrize("form", ["str", "path", "store"])
def test_a_whole_store_is_all_its_grids_minus_exclude(db, cli_whole, tmp_path, form):
    whole = {"str": str(db), "path": db, "store": specula.Store(db)}[form]
    s = specula.Store(tmp_path / "py.h5", "a")
    r = s.write_prior("w", [whole], exclude=["green-matte"], channels=2, components=2, epsilon=1e-2)
    assert_same_prior(s.path, "w", cli_whole[0])
    assert r["training"] == [f"{db}:blue-paint", f"{db}:gold"] and r["k"] == 2 and r["epsilon"] == 1e-2


def test_grids_in_memory_are_the_clis_prior_from_the_store(db, cli_specs, tmp_path):
    src = specula.Store(db)
    grids = {m: src.grid(m) for m in MATERIALS}
    s = specula.Store(tmp_path / "py.h5", "a")
    r = s.write_prior("d", grids, channels=2)
    assert_same_prior(s.path, "d", cli_specs[0], training=False)
    assert r["training"] == list(MATERIALS)
    # pairs mixed with a store's grid, one left out by its name
    items = [("blue-paint", grids["blue-paint"]), ("x", grids["gold"]), f"{db}:gold",
             ("green-matte", grids["green-matte"])]
    r = s.write_prior("m", items, exclude="x", channels=2)
    assert_same_prior(s.path, "m", cli_specs[0], training=False)
    assert r["training"] == ["blue-paint", f"{db}:gold", "green-matte"]


def priors(path):
    """The names of the priors a store holds, read with h5py."""
    with h5py.File(path, "r") as f:
        return sorted(f["priors"]) if "priors" in f else []


def test_a_with_block_commits_the_prior_with_the_rest(db, tmp_path):
    path = tmp_path / "w.h5"
    g = specula.Store(db).grid("gold")
    with specula.Store(path, "a") as s:
        s.write_grid("gold", g)
        s.write_prior("p", db, channels=2)
        assert not path.exists()
    assert s.grids == ["gold"] and priors(path) == ["p"]
    with pytest.raises(RuntimeError):
        with specula.Store(path, "a") as s:
            s.write_prior("q", db, channels=2)
            s.write_grid("g2", g)
            raise RuntimeError("abandon")
    assert specula.Store(path).grids == ["gold"] and priors(path) == ["p"]


def store_state(path):
    """The root's bytes and every committed data file's (an abandoned transaction's leftovers aside)."""
    files = sorted(p for p in path.parent.rglob("*") if p.is_file() and "tx" not in p.relative_to(path.parent).parts)
    return {str(p.relative_to(path.parent)): p.read_bytes() for p in files}


@pytest.fixture(scope="module")
def target(db, tmp_path_factory):
    """A store holding prior p, for writes that must fail."""
    s = specula.Store(tmp_path_factory.mktemp("target") / "out.h5", "a")
    s.write_prior("p", db, channels=2)
    return s


@pytest.mark.parametrize("name, grids, kwargs, error, message", [
    ("q", "DB:gold", {}, specula.UsageError, "write_prior: give at least 2 training grids (after exclude)"),
    ("q", "DB", {"exclude": ["DB:gold", "green-matte"]}, specula.UsageError,
     "write_prior: give at least 2 training grids (after exclude)"),
    ("q", ["DB:gold", "DB:nope"], {}, specula.InputError, "db.h5: no grid 'nope' (grids: blue-paint, gold"),
    ("q", ["DB:gold", "nothing.h5:a"], {}, specula.InputError, "nothing.h5: no such file"),
    ("bad/name", "DB", {}, specula.UsageError, "prior name 'bad/name' is not allowed"),
    ("q", ["DB:gold", "OTHER:cyan-gloss"], {}, specula.InputError,
     "other.h5:cyan-gloss' has bands 3 bands 400-700 nm step 150, not the 2 bands 400-700 nm step 300 of"),
    ("q", ["DB:gold", "gold.spgrid"], {}, specula.UsageError,
     "write_prior: 'gold.spgrid' is neither 'STORE.h5:NAME' nor a store; read the file"),
    ("q", "DB", {"channels": 1}, specula.UsageError, "channels must be 2 to 64"),
    ("q", "DB", {"channels": -1}, specula.UsageError, "write_prior: channels = -1: give 2 to 64"),
    ("q", "DB", {"components": -2}, specula.UsageError, "write_prior: components = -2: give a count (0: all)"),
    ("q", [("bad name", None), "DB:gold"], {}, specula.UsageError, "grid name 'bad name' is not allowed"),
    ("p", "DB", {}, specula.InputError, "out.h5: prior 'p' exists already; choose another name or give replace=True"),
])
def test_bad_input_is_one_line_and_leaves_the_store(db, target, name, grids, kwargs, error, message):
    path = Path(target.path)
    before = store_state(path)

    def fill(g):
        return g.replace("DB", str(db)).replace("OTHER", str(db.parent / "other.h5")) if isinstance(g, str) else g

    grids = fill(grids) if isinstance(grids, str) else [fill(g) for g in grids]
    kwargs = {"channels": 2, **kwargs, "exclude": [fill(e) for e in kwargs.get("exclude", [])]}
    with pytest.raises(error) as e:
        target.write_prior(name, grids, **kwargs)
    assert message in str(e.value) and "\n" not in str(e.value), str(e.value)
    assert store_state(path) == before


def test_replace_writes_over_a_prior(db, tmp_path):
    path = tmp_path / "r.h5"
    s = specula.Store(path, "a")
    s.write_prior("p", db, channels=2, components=1)
    s.write_prior("p", db, channels=2, components=2, replace=True)
    with h5py.File(path, "r") as f:
        assert f["priors/p/components"].shape[0] == 2


@pytest.mark.parametrize("grids, exclude, message", [
    (5, (), "write_prior: grids must be a sequence of grids or stores, or a dict of specula.Grids, not int"),
    ([("gold", np.zeros(3)), "x.h5:y"], (), "write_prior: grids[0] must be a specula.Grid, not ndarray"),
    ({"gold": "x"}, (), "write_prior: grids['gold'] must be a specula.Grid, not str"),
    ([3.5], (), "write_prior: grids[0] must be a 'STORE.h5:NAME' str"),
    (["x.h5:a", "x.h5:b"], [1], "write_prior: exclude[0] must be a str, not int"),
])
def test_wrong_types_are_one_type_error(tmp_path, grids, exclude, message):
    s = specula.Store(tmp_path / "t.h5", "a")
    with pytest.raises(TypeError) as e:
        s.write_prior("p", grids, exclude=exclude, channels=2)
    assert str(e.value).startswith(message) and "\n" not in str(e.value), str(e.value)
    assert not (tmp_path / "t.h5").exists()
