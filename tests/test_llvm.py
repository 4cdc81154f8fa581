import pytest

from convsss.errors import ConvsssError
from convsss.llvm import ENV, ensure_llvm, find_libllvm, llvm_version


def _touch(folder, name):
    path = folder / name
    path.write_bytes(b"")
    return path


@pytest.mark.parametrize("path, version", [
    ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", 19),
    ("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1", 15),
    ("/usr/lib/llvm-18/lib/libLLVM.so", 18),
    ("/opt/homebrew/opt/llvm/lib/libLLVM.dylib", None),
])
def test_version_from_name(path, version):
    assert llvm_version(path) == version


def test_newest_suitable_is_chosen(tmp_path):
    _touch(tmp_path, "libLLVM-15.so.1")
    _touch(tmp_path, "libLLVM.so.19.1")
    _touch(tmp_path, "libLLVM-17.so")
    assert find_libllvm([str(tmp_path)], environ={}).endswith("libLLVM.so.19.1")


def test_none_found_names_the_fix(tmp_path):
    _touch(tmp_path, "libLLVM-14.so.1")
    _touch(tmp_path, "libLLVM-15.so.1")
    with pytest.raises(ConvsssError, match=r"no libLLVM >= 17.*15, 14.*apt-get install libllvm19.*DRJIT_LIBLLVM_PATH"):
        find_libllvm([str(tmp_path)], environ={})
    with pytest.raises(ConvsssError, match="versions seen: none"):
        find_libllvm([str(tmp_path / "empty")], environ={})


def test_existing_variable_is_honoured(tmp_path):
    custom = _touch(tmp_path, "libLLVM-custom.so")
    env = {ENV: str(custom)}
    assert find_libllvm([], environ=env) == str(custom)
    with pytest.raises(ConvsssError, match="does not exist"):
        find_libllvm([], environ={ENV: str(tmp_path / "missing.so")})


def test_ensure_sets_variable(tmp_path, monkeypatch):
    lib = _touch(tmp_path, "libLLVM.so.19.1")
    env = {}
    monkeypatch.delitem(__import__("sys").modules, "drjit", raising=False)
    assert ensure_llvm([str(tmp_path)], environ=env) == str(lib)
    assert env[ENV] == str(lib)


def test_mitsuba_loads_with_discovered_llvm():
    from convsss.backend import load_mitsuba

    mi = load_mitsuba()
    import drjit as dr

    x = mi.Float([1.0, -2.0, 3.0])
    assert dr.minimum(x, 0.0).numpy().tolist() == [0.0, -2.0, 0.0]  # aborts the process with LLVM 15
