"""The archive for reviewers (written, verified, a changed file named), the reproducible PDF, and the
report without WeasyPrint's system libraries."""

import builtins
import io
import json
import tarfile
from pathlib import Path

import pytest

from stiffcal.workflow import archive as A
from stiffcal.cli import main
from stiffcal.errors import InputError
from stiffcal.report.html import image_data_uri, print_images, write_pdf


def _tree(tmp_path):
    (tmp_path / "results/tables").mkdir(parents=True)
    (tmp_path / "results/tables/t.csv").write_text("a,b\n1,2\n")
    (tmp_path / "config").mkdir()
    (tmp_path / "config/config.yaml").write_text("seed: 1\n")
    (tmp_path / "results/archive").mkdir()
    (tmp_path / "results/archive/old.tar.gz").write_bytes(b"x")
    return tmp_path


PROV = {"commit": "abc", "dirty": False, "started": "s", "ended": "e", "source_date_epoch": 1700000000}


FILES = [Path("config/config.yaml"), Path("results/tables/t.csv")]


def test_archive_holds_every_file_with_checksums_and_verifies(tmp_path, capsys):
    root = _tree(tmp_path)
    files = FILES
    out = A.write_archive(tmp_path / "out/stiffcal-abc.tar.gz", files, PROV, root)
    with tarfile.open(out) as tar:
        names = tar.getnames()
        prov = json.loads(tar.extractfile("stiffcal-abc/provenance.json").read())
        assert all(m.mtime == 1700000000 and m.uid == 0 for m in tar.getmembers())
    assert set(names) == {f"stiffcal-abc/{n}" for n in ("SHA256SUMS", "provenance.json", "config/config.yaml",
                                                           "results/tables/t.csv")}
    assert prov == PROV
    assert A.verify_archive(out) == (3, [])
    assert main(["verify-archive", str(out)]) == 0
    # the same files give the same bytes
    again = A.write_archive(tmp_path / "again/stiffcal-abc.tar.gz", files, PROV, root)
    assert again.read_bytes() == out.read_bytes()


def _tamper(src, dst, name, data):
    with tarfile.open(src) as tin, tarfile.open(dst, "w:gz") as tout:
        for m in tin.getmembers():
            content = tin.extractfile(m).read()
            if m.name.endswith(name):
                content, m.size = data, len(data)
            tout.addfile(m, io.BytesIO(content))


def test_a_changed_file_is_named(tmp_path, capsys):
    root = _tree(tmp_path)
    out = A.write_archive(tmp_path / "a/stiffcal-abc.tar.gz", FILES, PROV, root)
    bad = tmp_path / "bad.tar.gz"
    _tamper(out, bad, "results/tables/t.csv", b"a,b\n1,3\n")
    assert A.verify_archive(bad)[1] == ["changed: results/tables/t.csv"]
    assert main(["verify-archive", str(bad)]) == 1
    assert "changed: results/tables/t.csv" in capsys.readouterr().err


def test_not_an_archive_is_one_clear_error(tmp_path, capsys):
    junk = tmp_path / "junk.tar.gz"
    junk.write_text("not a tarball")
    with pytest.raises(InputError, match="not a readable .tar.gz archive"):
        A.verify_archive(junk)
    assert main(["verify-archive", str(junk)]) == 2
    assert "Traceback" not in capsys.readouterr().err


HTML = "<html><head><title>t</title></head><body><h1>Report</h1>" + "<p>text</p>" * 200 + "</body></html>"


def test_pdf_is_reproducible_with_dates_from_source_date_epoch(tmp_path, monkeypatch):
    pypdf = pytest.importorskip("pypdf")
    (tmp_path / "r.html").write_text(HTML)
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    pages = write_pdf(tmp_path / "r.html", tmp_path / "a.pdf")
    write_pdf(tmp_path / "r.html", tmp_path / "b.pdf")
    assert (tmp_path / "a.pdf").read_bytes() == (tmp_path / "b.pdf").read_bytes()
    reader = pypdf.PdfReader(tmp_path / "a.pdf")
    assert len(reader.pages) == pages >= 2
    assert reader.metadata["/CreationDate"].startswith("D:20231114")  # 1700000000 = 2023-11-14T22:13:20Z


def test_the_pdf_prints_an_embedded_svg_figure_from_its_png(tmp_path):
    pypdf = pytest.importorskip("pypdf")
    Image = pytest.importorskip("PIL.Image")
    svg = tmp_path / "fig.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="100pt" height="50pt" viewBox="0 0 100 50">'
                   + "".join(f'<circle cx="{i % 100}" cy="{i % 50}" r="1"/>' for i in range(200)) + "</svg>")
    Image.new("RGB", (40, 20), (200, 30, 30)).save(tmp_path / "fig.png")
    other = tmp_path / "other.svg"  # an SVG without a PNG in the map stays vector
    other.write_text('<svg xmlns="http://www.w3.org/2000/svg" width="10pt" height="10pt"><rect width="5" height="5"/>'
                     "</svg>")
    (tmp_path / "r.html").write_text(f'<html><body><img src="{image_data_uri(svg)}" style="width:10cm">'
                                     f'<img src="{image_data_uri(other)}"></body></html>')
    write_pdf(tmp_path / "r.html", tmp_path / "vector.pdf")
    write_pdf(tmp_path / "r.html", tmp_path / "print.pdf", print_images([svg]))
    images = [im.image.size for page in pypdf.PdfReader(tmp_path / "print.pdf").pages for im in page.images]
    assert images == [(40, 20)]  # the PNG, as it is
    assert not [im for page in pypdf.PdfReader(tmp_path / "vector.pdf").pages for im in page.images]


def test_without_weasyprint_libraries_the_pdf_fails_naming_the_library(tmp_path, monkeypatch):
    real = builtins.__import__

    def fake(name, *args, **kw):
        if name == "weasyprint":
            raise OSError("cannot load library 'libpango-1.0-0': libpango-1.0-0: cannot open shared object file")
        return real(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", fake)
    (tmp_path / "r.html").write_text(HTML)
    with pytest.raises(InputError) as err:
        write_pdf(tmp_path / "r.html", tmp_path / "r.pdf")
    assert "libpango-1.0-0" in str(err.value) and not (tmp_path / "r.pdf").exists()


@pytest.mark.parametrize("where,needle", [(0.5, "CRC check failed"), (-6, "CRC check failed"),
                                          (-2, "Incorrect length")])
def test_a_damaged_archive_is_reported_as_damaged(tmp_path, capsys, where, needle):
    """A flipped byte in the compressed data, or a damaged gzip trailer (CRC-32, length), is reported as a
    damaged archive with exit 1 (not as missing files, and never as verified)."""
    root = _tree(tmp_path)
    out = A.write_archive(tmp_path / "out/stiffcal-abc.tar.gz", FILES, PROV, root)
    raw = bytearray(out.read_bytes())
    i = int(len(raw) * where) if isinstance(where, float) else len(raw) + where
    raw[i] ^= 0x01
    bad = tmp_path / "bad.tar.gz"
    bad.write_bytes(bytes(raw))
    ok, problems = A.verify_archive(bad)
    assert ok == 0 and len(problems) == 1 and problems[0].startswith("damaged:") and needle in problems[0]
    assert main(["verify-archive", str(bad)]) == 1
    assert "damaged" in capsys.readouterr().err


def test_integrity_records_refuse_a_changed_or_truncated_file(tmp_path):
    from stiffcal import integrity

    f = tmp_path / "results/maps/m/map.csv"
    integrity.atomic_write(f, "a,b\n" + "1,2\n" * 100)
    integrity.record([f], "map_merge", root=tmp_path)
    integrity.verify([f], root=tmp_path)  # unchanged: fine
    f.write_text("a,b\n" + "1,2\n" * 50)  # cut in half
    with pytest.raises(InputError, match="changed after rule map_merge wrote it"):
        integrity.verify([f], root=tmp_path)
    assert [p.name for p in f.parent.iterdir()] == ["map.csv"]  # no temporary file left beside it


def test_the_archive_takes_every_file_the_config_names_and_refuses_a_missing_one(tmp_path):
    """config_files finds the robot files (and the URDF one reads, relative to the robot file), data CSVs and
    printed values wherever they lie, and nothing else; a file outside the root is packed under external/."""
    (tmp_path / "lab/urdf").mkdir(parents=True)
    (tmp_path / "lab/arm.yaml").write_text("name: arm\nkind: urdf\nurdf: urdf/arm.urdf\n")
    (tmp_path / "lab/urdf/arm.urdf").write_text("<robot name='arm'/>")
    (tmp_path / "lab/run1.csv").write_text("q1,q2\n0,0\n")
    (tmp_path / "printed.yaml").write_text("a: 1\n")
    outside = tmp_path.parent / f"{tmp_path.name}-outside.csv"
    outside.write_text("x\n1\n")
    config = {"seed": 1, "study": {"name": "lab", "robot": "lab/arm.yaml", "force_N": [0, -1]},
              "measured_data": [{"name": "run1", "data": "lab/run1.csv", "robot": "lab/arm.yaml",
                                 "discriminate": {"loads": "hanging:100,300"}},
                                {"name": "far", "data": str(outside), "robot": "lab/arm.yaml"}],
              "paper_values": "printed.yaml", "other": "lab/missing.csv"}
    files = A.config_files(config, tmp_path)
    assert [f.as_posix() for f in files] == sorted([outside.as_posix(), "lab/arm.yaml", "lab/run1.csv",
                                                    "lab/urdf/arm.urdf", "printed.yaml"])
    out = A.write_archive(tmp_path / "out/stiffcal-abc.tar.gz", files, PROV, tmp_path)
    with tarfile.open(out) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames()}
    assert names == {"lab/arm.yaml", "lab/run1.csv", "lab/urdf/arm.urdf", "printed.yaml", A.PROVENANCE, A.SUMS,
                     "external/" + outside.resolve().as_posix().lstrip("/")}
    assert A.verify_archive(out) == (6, [])
    with pytest.raises(InputError, match="missing: lab/gone.csv"):
        A.write_archive(tmp_path / "out2/stiffcal-abc.tar.gz", [*files, Path("lab/gone.csv")], PROV, tmp_path)
    assert not (tmp_path / "out2").exists()
