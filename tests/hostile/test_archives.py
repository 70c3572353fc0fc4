"""Hostile FMUs and SSP archives, generated here (nothing big committed): each is refused through
the real CLI with exit 2 and one line naming the file and what is wrong, nothing outside the
archive is loaded, followed or written, and a refused archive leaves no unpacked copy.

The FMU cases edit a copy of tests/data/LowPass (built by fmpy's own build, the ``lowpass_fmu``
fixture); the SSP cases wrap it in a one-component archive. A library outside the FMU is a
shared object whose constructor writes a marker file: the marker proves whether it was loaded.
"""

from __future__ import annotations

import hashlib
import os
import stat
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest

from twin.cli import main
from twin.fmu import external, safezip
from twin.fmu.library import required_functions
from twin.fmu.toolchain import cache_dir

LIBRARY = "binaries/linux64/LowPass.so"
MD = "modelDescription.xml"
pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="the corpus builds Linux libraries"
)

# ------------------------------------------------------------------------------ the building blocks


def _members(fmu: Path) -> list[tuple[zipfile.ZipInfo, bytes]]:
    with zipfile.ZipFile(fmu) as zf:
        return [(info, zf.read(info)) for info in zf.infolist()]


def _write(
    path: Path, members: list[tuple[zipfile.ZipInfo | str, bytes]], compression: int = zipfile.ZIP_DEFLATED
) -> Path:
    with zipfile.ZipFile(path, "w", compression) as zf:
        for info, data in members:  # a ZipInfo given is written as it says (its method, its mode)
            zf.writestr(info, data)
    return path


def _copy_info(info: zipfile.ZipInfo, compression: int) -> zipfile.ZipInfo:
    new = zipfile.ZipInfo(info.filename, info.date_time)
    new.external_attr, new.compress_type, new.create_system = (
        info.external_attr,
        compression,
        info.create_system,
    )
    return new


def _edit(
    src: Path,
    dst: Path,
    edit: Callable[[str, bytes], bytes | None],
    extra=(),
    compression=zipfile.ZIP_DEFLATED,
) -> Path:
    kept = [
        (_copy_info(i, compression), d2) for i, d in _members(src) if (d2 := edit(i.filename, d)) is not None
    ]
    return _write(dst, [*kept, *extra], compression)


def _md(change: Callable[[str], str], encoding: str = "utf-8") -> Callable[[str, bytes], bytes]:
    return lambda name, data: change(data.decode()).encode(encoding) if name == MD else data


def _identifier(value: str) -> Callable[[str, bytes], bytes]:
    return _md(lambda t: t.replace('modelIdentifier="LowPass"', f'modelIdentifier="{value}"'))


def _declared(text: str, encoding: str) -> str:
    """The modelDescription with its declaration naming ``encoding``."""
    head, _, body = text.partition("?>")
    assert head.startswith("<?xml"), head
    return f'<?xml version="1.0" encoding="{encoding}"?>{body}'


def _compile(folder: Path, name: str, code: str) -> Path:
    c, so = folder / f"{name}.c", folder / f"{name}.so"
    c.write_text(code)
    subprocess.run(["gcc", "-shared", "-fPIC", "-o", str(so), str(c)], check=True, capture_output=True)
    return so


_MARKER_CODE = """
#include <stdio.h>
#include <stdlib.h>
__attribute__((constructor)) static void planted(void) {
    const char *p = getenv("TWIN_HOSTILE_MARKER");
    if (p) { FILE *f = fopen(p, "w"); if (f) { fputs("ran\\n", f); fclose(f); } }
}
"""


@pytest.fixture()
def marker(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The file a planted library's constructor writes when it is loaded (it must never be)."""
    path = tmp_path / "PLANTED_LIBRARY_RAN"
    monkeypatch.setenv("TWIN_HOSTILE_MARKER", str(path))
    return path


@pytest.fixture()
def planted(tmp_path: Path) -> Path:
    """A library outside any FMU whose constructor writes the marker."""
    return _compile(tmp_path, "planted", _MARKER_CODE)


def _cli(args: list[str], capsys: pytest.CaptureFixture) -> tuple[int, list[str]]:
    capsys.readouterr()
    code = main(args)
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    return code, err.strip().splitlines()


def _refused(
    path: Path, words: str, capsys: pytest.CaptureFixture, tmp_path: Path, commands=("validate", "run")
) -> None:
    """``twin validate`` and ``twin run`` of ``path``: exit 2, one line naming it and ``words``."""
    out = tmp_path / "run-out"
    for command in commands:
        args = [command, str(path)] + (["--out", str(out), "--quiet"] if command == "run" else [])
        code, lines = _cli(args, capsys)
        assert code == 2 and len(lines) == 1, (command, lines)
        assert str(path.name) in lines[0] and words in lines[0], (command, lines[0])
    assert not out.exists()


# ------------------------------------------------------------------------- external FMUs: the library


@pytest.mark.parametrize("where", ["absolute", "climbs", "separator", "not-a-c-name"])
def test_a_model_identifier_naming_a_library_outside_the_fmu_is_refused_and_nothing_loads(
    where: str, tmp_path: Path, lowpass_fmu: Path, planted: Path, marker: Path, capsys: pytest.CaptureFixture
) -> None:
    stem = str(planted.with_suffix(""))
    value = {
        "absolute": stem,  # fmpy would load <unzipdir>/binaries/linux64//tmp/.../planted.so = the planted one
        "climbs": "../../../../../../../../../.." + stem,
        "separator": "sub/LowPass",
        "not-a-c-name": "Low Pass",
    }[where]
    fmu = _edit(lowpass_fmu, tmp_path / "Evil.fmu", _identifier(value))
    _refused(fmu, f"modelIdentifier {value!r} is not a plain C name", capsys, tmp_path)
    # as a scenario's FMU too: the line names the key
    scenario = tmp_path / "with-evil.toml"
    scenario.write_text(
        '[scenario]\nname = "e"\nduration = "1 s"\nstep = "0.1 s"\n[fmu.f]\nmodel = "Evil.fmu"\n'
    )
    code, lines = _cli(["validate", str(scenario)], capsys)
    assert code == 2 and any("fmu.f.model" in ln and "not a plain C name" in ln for ln in lines), lines
    assert not marker.exists(), "the planted library was loaded"


def test_a_symlinked_library_member_is_refused(
    tmp_path: Path, lowpass_fmu: Path, planted: Path, marker: Path, capsys: pytest.CaptureFixture
) -> None:
    link = zipfile.ZipInfo(LIBRARY)
    link.create_system, link.external_attr = 3, (stat.S_IFLNK | 0o777) << 16
    fmu = _edit(
        lowpass_fmu,
        tmp_path / "Linked.fmu",
        lambda n, d: None if n == LIBRARY else d,
        [(link, str(planted).encode())],
    )
    _refused(fmu, f"member {LIBRARY!r}: a symbolic link", capsys, tmp_path)
    assert not marker.exists()


def test_a_library_that_is_no_elf_file_is_one_line(
    tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    fmu = _edit(
        lowpass_fmu,
        tmp_path / "NotElf.fmu",
        lambda n, d: b"#!/bin/sh\necho not a library\n" if n == LIBRARY else d,
    )
    _refused(fmu, f"{LIBRARY} is not a shared library (no ELF header)", capsys, tmp_path)


def test_a_library_without_fmi2_cancel_step_is_refused_before_any_of_its_code_runs(
    tmp_path: Path, lowpass_fmu: Path, marker: Path, capsys: pytest.CaptureFixture
) -> None:
    """Every fmi2 function but fmi2CancelStep, and a constructor: read from its ELF headers, the
    library is refused without being loaded (fmpy would load it, run the constructor, then fail
    with an AttributeError traceback)."""
    stubs = "".join(
        f"int {name}(void) {{ return 0; }}\n" for name in sorted(required_functions() - {"fmi2CancelStep"})
    )
    lib = _compile(tmp_path, "nocancel", _MARKER_CODE + stubs)
    fmu = _edit(lowpass_fmu, tmp_path / "NoCancel.fmu", lambda n, d: lib.read_bytes() if n == LIBRARY else d)
    _refused(
        fmu,
        f"{LIBRARY} lacks fmi2CancelStep: an FMI 2.0 co-simulation library exports every fmi2 function",
        capsys,
        tmp_path,
    )
    assert not marker.exists(), "the library's code ran"


def test_a_library_the_loader_refuses_is_one_line_and_the_working_folder_is_kept(
    tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    """Every fmi2 function, but a dependency that is nowhere: the loader refuses it (what no
    header says); one line, and fmpy's change of the working folder is undone."""
    stubs = "".join(f"int {name}(void) {{ return 0; }}\n" for name in sorted(required_functions()))
    dep = _compile(tmp_path, "libgone", "int gone(void) { return 1; }\n")
    c = tmp_path / "needs.c"
    c.write_text("int gone(void);\nint use(void) { return gone(); }\n" + stubs)
    lib = tmp_path / "needs.so"
    subprocess.run(
        ["gcc", "-shared", "-fPIC", "-o", str(lib), str(c), "-L", str(tmp_path), "-lgone"], check=True
    )
    dep.unlink()
    fmu = _edit(lowpass_fmu, tmp_path / "Needs.fmu", lambda n, d: lib.read_bytes() if n == LIBRARY else d)
    cwd = os.getcwd()
    _refused(fmu, "cannot load its library: libgone.so: cannot open shared object file", capsys, tmp_path)
    assert os.getcwd() == cwd


def test_the_library_loaded_is_the_checked_member_inside_the_private_extraction(
    tmp_path: Path, lowpass_fmu: Path
) -> None:
    from twin.fmu.slot import FMUSlot
    from twin.fmu.workdir import process_dir

    fmu = tmp_path / "LowPass.fmu"
    fmu.write_bytes(lowpass_fmu.read_bytes())
    with zipfile.ZipFile(fmu) as zf:
        member_sha = hashlib.sha256(zf.read(LIBRARY)).hexdigest()
    slot = FMUSlot(fmu, "lowpass")
    try:
        library = Path(slot.library)
        assert library.is_relative_to(Path(slot.unzipdir)) and Path(slot.unzipdir).is_relative_to(
            process_dir()
        )
        assert not library.is_symlink() and hashlib.sha256(library.read_bytes()).hexdigest() == member_sha
        maps = Path("/proc/self/maps").read_text()
        assert str(library) in maps  # the file the loader mapped is that one
        assert not (library.parent.parent.parent / ".fmu").exists()  # the hashed copy is gone once unpacked
    finally:
        slot.close()


def test_an_fmu_replaced_after_its_check_with_the_same_size_and_time_is_not_unpacked(
    tmp_path: Path, lowpass_fmu: Path
) -> None:
    from twin.errors import ConfigError
    from twin.fmu.slot import FMUSlot

    fmu = tmp_path / "Swapped.fmu"
    fmu.write_bytes(lowpass_fmu.read_bytes())
    external.check(fmu)
    st = fmu.stat()
    data = bytearray(fmu.read_bytes())
    data[-30] ^= 0xFF
    fmu.write_bytes(bytes(data))
    os.utime(fmu, ns=(st.st_atime_ns, st.st_mtime_ns))
    with pytest.raises(ConfigError, match="changed since it was checked"):
        FMUSlot(fmu, "swapped")


# ------------------------------------------------------------------ external FMUs: the archive itself


def _stored_flip(src: Path, dst: Path) -> Path:
    """The library stored (not deflated) with one byte of its data flipped: a bad CRC."""
    _edit(src, dst, lambda n, d: d, compression=zipfile.ZIP_STORED)
    data = bytearray(dst.read_bytes())
    with zipfile.ZipFile(dst) as zf:
        info = zf.getinfo(LIBRARY)
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    data[start + info.compress_size // 2] ^= 0xFF
    dst.write_bytes(bytes(data))
    return dst


def _deflate_broken(src: Path, dst: Path) -> Path:
    """The library's deflate stream cut short in the middle (the sizes kept): a damaged member."""
    _edit(src, dst, lambda n, d: d)
    data = bytearray(dst.read_bytes())
    with zipfile.ZipFile(dst) as zf:
        info = zf.getinfo(LIBRARY)
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    data[start : start + info.compress_size] = bytes([0xFF]) * info.compress_size
    dst.write_bytes(bytes(data))
    return dst


def _extra(name: str | zipfile.ZipInfo, data: bytes = b"x"):
    return lambda src, dst: _edit(src, dst, lambda n, d: d, [(name, data)])


LONG = "resources/" + "a" * 300
FMU_CASES: dict[str, tuple[Callable[[Path, Path], Path], str]] = {
    "bad-crc": (_stored_flip, f"member {LIBRARY!r} is damaged: Bad CRC-32"),
    "damaged-member": (_deflate_broken, f"member {LIBRARY!r} is damaged"),
    "absolute-name": (_extra("/tmp/twin-hostile-absolute"), "an absolute path"),
    "climbing-name": (_extra("resources/../../escaped"), "a '..' in its name"),
    "colon-name": (_extra("resources/c:x"), "a colon in its name"),
    "dot-name": (_extra("resources/./x"), "an empty or '.' part in its name"),
    "300-characters": (_extra(LONG), "a part of its name longer than 255 bytes"),
    "file-and-folder": (
        lambda src, dst: _edit(
            src, dst, lambda n, d: d, [("resources/zz", b"x"), ("resources/zz/inner", b"y")]
        ),
        "member 'resources/zz/inner' lies in 'resources/zz', which is a file of the archive",
    ),
    "ratio-bomb": (_extra("resources/filler", bytes(4 << 20)), "more than 100 times (a zip bomb's ratio)"),
    "xml-shift-jis": (
        lambda src, dst: _edit(
            src,
            dst,
            _md(
                lambda t: _declared(t, "Shift_JIS").replace('description="', 'description="\u8a66', 1),
                "shift_jis",
            ),
        ),
        "modelDescription.xml: encoding 'Shift_JIS': the twin reads XML in UTF-8 or UTF-16",
    ),
    "xml-utf-7": (
        lambda src, dst: _edit(src, dst, _md(lambda t: _declared(t, "UTF-7"), "utf-7")),
        "modelDescription.xml: encoding 'UTF-7'",
    ),
    "xml-utf-16-doctype": (
        lambda src, dst: _edit(
            src,
            dst,
            _md(
                lambda t: _declared(t, "UTF-16").replace("?>", '?>\n<!DOCTYPE x [<!ENTITY e "e">]>', 1),
                "utf-16",
            ),
        ),
        "modelDescription.xml: XML with a document type declaration is not read",
    ),
    "xml-utf-16-external-entity": (
        lambda src, dst: _edit(
            src,
            dst,
            _md(
                lambda t: (
                    _declared(t, "UTF-16")
                    .replace("?>", '?>\n<!DOCTYPE x [<!ENTITY e SYSTEM "/etc/passwd">]>', 1)
                    .replace('description="', 'description="&e;', 1)
                ),
                "utf-16",
            ),
        ),
        "modelDescription.xml: XML with a document type declaration is not read",
    ),
}


@pytest.mark.parametrize("case", sorted(FMU_CASES))
def test_a_hostile_fmu_archive_is_one_line(
    case: str, tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    make, words = FMU_CASES[case]
    fmu = make(lowpass_fmu, tmp_path / f"{case}.fmu")
    _refused(fmu, words, capsys, tmp_path)
    assert not Path("/tmp/twin-hostile-absolute").exists() and not (tmp_path.parent / "escaped").exists()


def test_a_utf_16_model_description_without_a_document_type_is_read(
    tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    """UTF-16 is an encoding every XML reader knows: refused only with a document type."""
    fmu = _edit(lowpass_fmu, tmp_path / "Utf16.fmu", _md(lambda t: _declared(t, "UTF-16"), "utf-16"))
    code, lines = _cli(["validate", str(fmu)], capsys)
    assert code == 0, lines


def _patch_central_sizes(path: Path, size: int) -> None:
    """Every stored member's central directory entry made to claim ``size`` bytes (packed and unpacked)."""
    data = bytearray(path.read_bytes())
    at = data.find(b"PK\x01\x02")
    while at != -1:
        data[at + 20 : at + 28] = size.to_bytes(4, "little") * 2
        at = data.find(b"PK\x01\x02", at + 4)
    path.write_bytes(bytes(data))


def test_headers_that_lie_are_caught_from_the_headers_and_while_unpacking(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # the headers claim 3 x 200 MB stored (ratio 1, each under the member cap): the total is refused
    big = _write(
        tmp_path / "claims.fmu", [(f"resources/r{i}", b"x" * 100) for i in range(3)], zipfile.ZIP_STORED
    )
    _patch_central_sizes(big, 200 << 20)
    code, lines = _cli(["validate", str(big)], capsys)
    assert code == 2 and len(lines) == 1 and f"more than {safezip.MAX_UNPACKED_BYTES >> 20} MB" in lines[0], (
        lines
    )
    # a header claiming 10 MB packed into 200 MB (a ratio of 20) in a file of a few hundred bytes
    claims = _write(tmp_path / "packed.fmu", [("resources/r", b"x" * 100)], zipfile.ZIP_STORED)
    data = bytearray(claims.read_bytes())
    at = data.find(b"PK\x01\x02")
    data[at + 20 : at + 28] = (10 << 20).to_bytes(4, "little") + (200 << 20).to_bytes(4, "little")
    claims.write_bytes(bytes(data))
    code, lines = _cli(["validate", str(claims)], capsys)
    assert (
        code == 2 and len(lines) == 1 and "its headers claim 10485760 packed bytes in a file of" in lines[0]
    ), lines
    # a header that says 1 000 bytes of a member that unpacks to 800 KB: never more than it said
    small = tmp_path / "small.zip"
    with zipfile.ZipFile(small, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("resources/r", os.urandom(400 << 10).hex().encode()[: 800 << 10])
    with zipfile.ZipFile(small) as zf:
        info = zf.getinfo("resources/r")
        info.file_size = 1000  # what a lying central directory would say
        got = []
        with pytest.raises(Exception, match=r"is damaged: Bad CRC-32|unpacks to more than"):
            safezip.copy_member(zf, info, got.append, str(small))
        assert sum(map(len, got)) <= 1000


# -------------------------------------------------------------------- files that are not archives


@pytest.mark.parametrize("kind", ["fifo", "dev-zero"])
@pytest.mark.parametrize("suffix", [".fmu", ".ssp"])
def test_a_fifo_or_a_device_is_refused_at_once(kind: str, suffix: str, tmp_path: Path) -> None:
    """In a process of its own, with a timeout: a reader that blocked would hang the suite."""
    path = tmp_path / f"blocking{suffix}"
    if kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to("/dev/zero")
    out = tmp_path / "out"
    for args in (["validate", str(path)], ["run", str(path), "--out", str(out), "--quiet"]):
        done = subprocess.run(
            [sys.executable, "-m", "twin", *args], capture_output=True, text=True, timeout=60
        )
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1, done.stderr
        assert str(path) in lines[0] and "is not a regular file" in lines[0], lines[0]
    assert not out.exists()


# ---------------------------------------------------------------------------------- SSP archives

SSD_NS = 'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"'


def _ssd(component: str = 'source="resources/LowPass.fmu"', encoding: str = "UTF-8", head: str = "") -> str:
    return (
        f'<?xml version="1.0" encoding="{encoding}"?>{head}<ssd:SystemStructureDescription {SSD_NS} version="1.0" name="s">'
        f'<ssd:System name="s"><ssd:Elements><ssd:Component name="f" {component}/></ssd:Elements></ssd:System>'
        '<ssd:DefaultExperiment startTime="0.0" stopTime="1.0"/></ssd:SystemStructureDescription>'
    )


def _ssp(path: Path, lowpass: Path, ssd: bytes | None = None, extra=()) -> Path:
    members = [
        ("SystemStructure.ssd", ssd if ssd is not None else _ssd().encode()),
        ("resources/LowPass.fmu", lowpass.read_bytes()),
    ]
    return _write(path, [*members, *extra])


def _unpacked(path: Path) -> Path:
    return cache_dir() / "ssp" / hashlib.sha256(path.read_bytes()).hexdigest()[:32]


SSP_CASES: dict[str, tuple[Callable[[Path, Path], Path], str]] = {
    "absolute-name": (
        lambda p, f: _ssp(p, f, extra=[("/tmp/twin-hostile-absolute", b"x")]),
        "an absolute path",
    ),
    "climbing-name": (lambda p, f: _ssp(p, f, extra=[("../../escaped", b"x")]), "a '..' in its name"),
    "colon-name": (lambda p, f: _ssp(p, f, extra=[("c:x", b"x")]), "a colon in its name"),
    "dot-name": (
        lambda p, f: _ssp(p, f, extra=[(".", b"x")]),
        "member '.': an empty or '.' part in its name",
    ),
    "300-characters": (lambda p, f: _ssp(p, f, extra=[(LONG, b"x")]), "longer than 255 bytes"),
    "file-and-folder": (
        lambda p, f: _ssp(p, f, extra=[("zz", b"x"), ("zz/inner", b"y")]),
        "member 'zz/inner' lies in 'zz', which is a file of the archive",
    ),
    "symlink-member": (
        lambda p, f: _ssp(p, f, extra=[(_link("resources/link.ssv", "/etc/passwd"), b"/etc/passwd")]),
        "member 'resources/link.ssv': a symbolic link",
    ),
    "ssd-shift-jis": (
        lambda p, f: _ssp(
            p, f, _ssd(encoding="Shift_JIS").replace('name="s">', 'name="\u8a66">', 1).encode("shift_jis")
        ),
        "SystemStructure.ssd: encoding 'Shift_JIS'",
    ),
    "ssd-utf-7": (
        lambda p, f: _ssp(p, f, _ssd(encoding="UTF-7").encode("utf-7")),
        "SystemStructure.ssd: encoding 'UTF-7'",
    ),
    "ssd-utf-16-doctype": (
        lambda p, f: _ssp(
            p, f, _ssd(encoding="UTF-16", head='<!DOCTYPE x [<!ENTITY e "e">]>').encode("utf-16")
        ),
        "SystemStructure.ssd: XML with a document type declaration is not read",
    ),
    "ssv-utf-16-external-entity": (
        lambda p, f: _ssp(
            p,
            f,
            extra=[
                (
                    "resources/values.ssv",
                    '<?xml version="1.0" encoding="UTF-16"?><!DOCTYPE x [<!ENTITY e SYSTEM "/etc/passwd">]><x>&e;</x>'.encode(
                        "utf-16"
                    ),
                )
            ],
        ),
        "resources/values.ssv: XML with a document type declaration is not read",
    ),
    # the parameter mapping that inflated to 6.5 GB: any member's ratio is capped from its header
    "ssm-ratio-bomb": (
        lambda p, f: _ssp(p, f, extra=[("resources/map.ssm", b"<a>" + b" " * (8 << 20) + b"</a>")]),
        "member 'resources/map.ssm': unpacks",
    ),
    # bzip2 (the 6.5 GB mapping was packed so: zipfile unpacks a bzip2 block whole, in memory)
    "ssm-bzip2": (
        lambda p, f: _ssp(p, f, extra=[(_bzip2("resources/map.ssm"), b"<a>" + b" " * 1000 + b"</a>")]),
        "member 'resources/map.ssm': packed with bzip2: FMUs and SSP archives are packed with deflate or stored",
    ),
    # a mapping within the ratio but above the XML cap (random text packs about 1.3:1)
    "ssm-too-large": (
        lambda p, f: _ssp(
            p,
            f,
            extra=[("resources/map.ssm", b"<a>" + os.urandom(9 << 20).hex().encode()[: 17 << 20] + b"</a>")],
        ),
        "resources/map.ssm: larger than 16 MB",
    ),
    # the 2.3 MB archive that unpacked 2.1 GB into the cache
    "unpacks-gigabytes": (
        lambda p, f: _ssp(p, f, extra=[(f"resources/filler{i}", bytes(3 << 20)) for i in range(3)]),
        "more than 100 times (a zip bomb's ratio)",
    ),
}


def _bzip2(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name)
    info.compress_type = zipfile.ZIP_BZIP2
    return info


def _link(name: str, target: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name)
    info.create_system, info.external_attr = 3, (stat.S_IFLNK | 0o777) << 16
    return info


@pytest.mark.parametrize("case", sorted(SSP_CASES))
def test_a_hostile_ssp_archive_is_one_line_and_leaves_nothing_unpacked(
    case: str, tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    make, words = SSP_CASES[case]
    ssp = make(tmp_path / f"{case}.ssp", lowpass_fmu)
    _refused(ssp, words, capsys, tmp_path)
    assert not _unpacked(ssp).exists()
    assert not Path("/tmp/twin-hostile-absolute").exists() and not (tmp_path.parent / "escaped").exists()


def test_an_ssp_refused_after_it_was_unpacked_leaves_no_copy_in_the_cache(
    tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    """Schema-valid, unpacked, then refused by the reader (its FMU breaks the rules): the
    unpacked copy goes with the refusal."""
    evil = _edit(lowpass_fmu, tmp_path / "evil.fmu", _identifier("../../evil"))
    ssp = _write(
        tmp_path / "refused.ssp",
        [("SystemStructure.ssd", _ssd().encode()), ("resources/LowPass.fmu", evil.read_bytes())],
    )
    _refused(ssp, "not a plain C name", capsys, tmp_path)
    assert not _unpacked(ssp).exists()
    assert not list((cache_dir() / "ssp").glob(f".{_unpacked(ssp).name}.*"))


def test_an_ssp_whose_fmu_refuses_its_parameter_leaves_no_copy_in_the_cache(
    tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    """Refused only when the FMU is initialized (LowPass, its declared minimum of T taken out,
    refuses T <= 0 in fmi2ExitInitializationMode): the copy the archive was unpacked to goes too."""
    binding = (
        "<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues>"
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="p">'
        '<ssv:Parameters><ssv:Parameter name="T"><ssv:Real value="-1.0"/></ssv:Parameter></ssv:Parameters>'
        "</ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"
    )
    ssd = _ssd().replace(
        'source="resources/LowPass.fmu"/>', f'source="resources/LowPass.fmu">{binding}</ssd:Component>'
    )
    unbounded = _edit(lowpass_fmu, tmp_path / "LowPass.fmu", _md(lambda t: t.replace(' min="1e-6"', "")))
    ssp = _ssp(tmp_path / "negative.ssp", unbounded, ssd.encode())
    code, lines = _cli(["validate", str(ssp), "--step-size", "0.1"], capsys)
    assert code == 2 and len(lines) == 1 and "T must be a positive finite time constant" in lines[0], lines
    assert not _unpacked(ssp).exists()


def test_a_sound_archive_of_the_same_shape_runs(
    tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    """The cases above differ from this one by their hostile part only: it is accepted."""
    ssp = _ssp(tmp_path / "sound.ssp", lowpass_fmu, _ssd(encoding="UTF-16").encode("utf-16"))
    code, lines = _cli(["validate", str(ssp), "--step-size", "0.1"], capsys)
    assert code == 0, lines
    assert (_unpacked(ssp) / ".complete").is_file()


def test_every_limit_is_stated_in_the_docs() -> None:
    docs = (Path(__file__).parents[2] / "docs" / "fmi-tools.md").read_text()
    for number in (
        f"{safezip.MAX_ARCHIVE_BYTES >> 20} MB",
        f"{safezip.MAX_MEMBER_BYTES >> 20} MB",
        f"{safezip.MAX_UNPACKED_BYTES >> 20} MB",
        f"{safezip.MAX_RATIO}",
        f"{safezip.MAX_MEMBERS}",
    ):
        assert number in docs, number


def test_a_full_disk_while_unpacking_is_not_called_a_damaged_member(tmp_path: Path) -> None:
    """The sink's own error (here a full disk) goes up as itself: the member is sound."""
    import errno

    path = tmp_path / "sound.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("data.bin", b"x" * 4096)

    def full(_block: bytes) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    with zipfile.ZipFile(path) as zf, pytest.raises(OSError, match="No space left") as caught:
        safezip.copy_member(zf, zf.getinfo("data.bin"), full, str(path))
    assert "damaged" not in str(caught.value)
    with zipfile.ZipFile(path) as zf:  # and a sound sink takes every byte
        blocks: list[bytes] = []
        assert safezip.copy_member(zf, zf.getinfo("data.bin"), blocks.append, str(path)) == 4096
