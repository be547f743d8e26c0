"""The HTML report (Jinja2) and its PDF (WeasyPrint), built only from generated files.

Every number in the report comes from a CSV under ``results/`` or from the config; the template holds
words only. Figures are embedded as SVG (vector) data URIs, so the HTML opens offline as one file and the
figures stay crisp at any zoom and in the PDF. A table of contents links every section (the PDF gets the
same headings as bookmarks).
"""

from __future__ import annotations

import base64
import hashlib
import json
import math
from pathlib import Path

from ..errors import InputError

TEMPLATE_DIR = Path(__file__).resolve().parents[3] / "paper" / "templates"


def fmt(x, digits: int = 4) -> str:
    """Format a number for the report: fixed decimals, 'inf' for infinity, '' for missing."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    if isinstance(x, str):
        return x
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if abs(x) >= 1e6:
        return f"{x:.{digits}e}"
    text = f"{x:.{digits}f}"
    return text.lstrip("-") if float(text) == 0 else text


def fmt_like(x, printed: str, extra: int = 2) -> str:
    """Format ``x`` with the printed number's decimals plus ``extra`` (to show where they differ)."""
    from ..paper.reproduction import printed_decimals

    if isinstance(x, str) or " " in printed:  # a pose, already formatted
        return fmt(x)
    return fmt(x, printed_decimals(printed) + extra)


def image_data_uri(path: str | Path) -> str:
    """SVG or PNG file -> ``data:image/...;base64,...`` (embedded so the HTML is self-contained)."""
    path = Path(path)
    kind = "svg+xml" if path.suffix == ".svg" else "png"
    return f"data:image/{kind};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _slug(text: str, used: set) -> str:
    import re

    base = re.sub(r"[^a-z0-9]+", "-", re.sub(r"<[^>]+>", "", text).lower()).strip("-") or "section"
    slug, k = base, 2
    while slug in used:
        slug, k = f"{base}-{k}", k + 1
    used.add(slug)
    return slug


def add_toc(html: str, marker: str = "<!-- toc -->") -> str:
    """Give every ``<h2>``/``<h3>`` an id (keeping one it has) and put a linked table of contents at
    ``marker``: one entry per h2, its h3s nested beneath."""
    import re

    used: set = set(re.findall(r'<h[23][^>]*\bid="([^"]+)"', html))
    entries = []

    def name(m):
        level, attrs, text = m.group(1), m.group(2), m.group(3)
        idm = re.search(r'\bid="([^"]+)"', attrs)
        ident = idm.group(1) if idm else _slug(text, used)
        entries.append((int(level), ident, re.sub(r"<(?!/?(sub|sup|i|b)\b)[^>]+>", "", text).strip()))
        return f'<h{level}{attrs}>{text}</h{level}>' if idm else f'<h{level} id="{ident}"{attrs}>{text}</h{level}>'

    body = re.sub(r"<h([23])([^>]*)>(.*?)</h\1>", name, html, flags=re.S)
    items, open_sub = [], False
    for level, ident, text in entries:
        if level == 2:
            items.append(("</ul></li>" if open_sub else "</li>") if items else "")
            items.append(f'<li><a href="#{ident}">{text}</a>')
            open_sub = False
        else:
            items.append("" if open_sub else "<ul>")
            items.append(f'<li><a href="#{ident}">{text}</a></li>')
            open_sub = True
    if items:
        items.append("</ul></li>" if open_sub else "</li>")
    toc = '<nav class="toc"><h2 class="toc-title">Contents</h2><ul>' + "".join(items) + "</ul></nav>"
    return body.replace(marker, toc, 1)


def config_hash(config: dict) -> str:
    """SHA-256 (first 12 hex digits) of the config, canonicalised as sorted JSON."""
    return hashlib.sha256(json.dumps(config, sort_keys=True, allow_nan=False).encode()).hexdigest()[:12]


def render_html(context: dict, template_dir: str | Path = TEMPLATE_DIR) -> str:
    """Render ``report.html.j2`` with ``context``; undefined names are errors, not blanks."""
    import jinja2

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(template_dir)),
                             undefined=jinja2.StrictUndefined, autoescape=jinja2.select_autoescape(["html"]),
                             trim_blocks=True, lstrip_blocks=True, extensions=["jinja2.ext.do"])
    env.filters["num"] = fmt
    env.filters["num_like"] = fmt_like
    env.filters["poses"] = parse_poses
    return add_toc(env.get_template("report.html.j2").render(**context))


def parse_poses(text: str) -> list[list[float]]:
    """'q1 q2; q1 q2' (a plan in a CSV cell) -> [[q1, q2], [q1, q2]] [deg], for pose tables."""
    return [[float(v) for v in p.split()] for p in str(text).split(";") if p.strip()]


def build_context(config: dict, tables: dict[str, str | Path], figures: dict[str, str | Path],
                  printed_path: str | Path, provenance: dict) -> dict:
    """Collect everything the template shows.

    tables: name -> CSV path (table2, table3, comparison, validation); figures: name -> PNG path;
    provenance: rule name per table/figure plus 'commit' and 'config_hash'.
    """
    import pandas as pd

    from ..planning.maps import DARK_CHI, WHITE_CHI
    from ..paper.reproduction import FLAT_RTOL, summary

    frames = {k: pd.read_csv(v, keep_default_na=False, na_values=[""], dtype={"printed": str, "reason": str})
              for k, v in tables.items()}
    from ..validation import read_yaml

    printed = read_yaml(printed_path)
    cmp = frames["comparison"]
    cmp["reason"] = cmp["reason"].fillna("")
    cmp["ours"] = pd.to_numeric(cmp["ours"], errors="coerce").where(lambda v: v.notna(), cmp["ours"])
    records = cmp.to_dict("records")
    return {
        "config": config,
        "study": config["study"],
        "tables": {k: df.to_dict("records") for k, df in frames.items()},
        "comparison_tables": [r for r in records if r["table"] != "text"],
        "comparison_text": [{**r, **printed.get("text", {}).get(r["row"], {})}
                            for r in records if r["table"] == "text"],
        "n_joints": len(config["study"]["test_pose_deg"]),
        "figures": {k: image_data_uri(v) for k, v in figures.items()},
        "summary": summary(cmp),
        "notes": printed.get("notes", {}),
        "provenance": provenance,
        "flat_rtol": FLAT_RTOL,
        "printed": printed,
        "cmp_index": comparison_index(records, printed),
        "map_thresholds": {"white_inv_chi": 1.0 / WHITE_CHI, "dark_inv_chi": 1.0 / DARK_CHI},
    }


def comparison_index(records: list[dict], printed: dict) -> dict:
    """'table|criterion|quantity' -> the paper's printed number beside ours in Tables 2-5 (printed, status,
    reason, alias). A printed row that stands for several of our rows (Table 2's "O2, O4", Table 3's
    "D-optimality (O1)", listed under ``criteria`` in the printed values) is indexed under the first, and
    under the others with ``alias`` set to the first (so that each printed number is shown once)."""
    out = {}
    for r in records:
        if r["table"] == "text":
            continue
        keys = printed.get(r["table"], {}).get(r["row"], {}).get("criteria", [r["row"]])
        entry = {"printed": r["printed"], "status": r["status"], "reason": r["reason"], "alias": None}
        out[f"{r['table']}|{keys[0]}|{r['quantity']}"] = entry
        for k in keys[1:]:
            out[f"{r['table']}|{k}|{r['quantity']}"] = {**entry, "alias": keys[0]}
    return out


def robot_summary(study) -> dict:
    """The robot of a design study as its report section shows it: name, kind, joints n, identifiable compliances
    n_params (joints whose axis passes through every measured point are left out: ``inert``), equations per pose
    d, source, DH table, tool, limits (``limited``: per joint; a continuous joint has none), joint names, URDF."""
    import numpy as np

    from ..planning.problem import unidentified_notes

    robot = study.robot
    prob = study.problem("ot")
    dh = None
    if robot.dh is not None:
        dh = [{"a_m": r[0], "alpha_deg": float(np.degrees(r[1])), "d_m": r[2], "offset_deg": float(np.degrees(r[3]))}
              for r in robot.dh]
    return {"name": robot.name, "kind": robot.kind, "n": robot.n_joints, "n_params": prob.n_params,
            "d": prob.rows_per_pose, "source": robot.reference, "dh": dh, "convention": robot.convention,
            "tool_m": None if robot.tool_m is None else robot.tool_m.tolist(),
            "limits_deg": _limits_text(np.degrees(robot.joint_limits_rad)),
            "has_limits": robot.has_joint_limits, "limited": robot.limited.tolist(),
            "inert": [robot.joint_names[j] for j in range(robot.n_joints) if j not in prob.params],
            "inert_notes": unidentified_notes(robot, prob),
            "joint_keys": robot.joint_columns(""), "joint_names": list(robot.joint_names), "urdf": robot.urdf}


def _limits_text(limits_deg) -> list[list[str]]:
    """The joint limits (n, 2) [deg] as the report prints them: rounded inward to 2 decimals, trailing zeros dropped
    (a URDF's 3.5 rad, 200.5352 deg, was printed "201", beside a pose at 200.54 in its plan)."""
    from ..model.robot import round_within

    lo, hi = round_within(limits_deg.T, limits_deg, 2)  # each limit held within itself, as the poses are
    return [[f"{v:.2f}".rstrip("0").rstrip(".") for v in pair] for pair in zip(lo, hi)]


def study_context(study, entry: dict, paths: dict) -> dict:
    """What the report shows of one design study: the robot (:func:`robot_summary`), test pose, force, sigma, the
    certificate, the plans against M and the two figures (embedded)."""
    import numpy as np
    import pandas as pd

    from ..model.robot import round_within
    from ..model.workcell import cell_notes, contact_note, test_pose_note
    from ..planning.problem import weak_compliance_notes

    robot = study.robot
    versus_m = pd.read_csv(paths["studym"], keep_default_na=False, na_values=[""])
    long = pd.read_csv(paths["studyplans"], keep_default_na=False, na_values=[""])
    cols = robot.joint_columns("q", "_deg")
    poses = {int(m): round_within(g[cols].to_numpy(float), robot.limits_deg, 2).tolist()  # printed within limits
             for m, g in long.groupby("m", sort=True)}
    clearance = ({int(m): [(float(c), str(n)) for c, n in zip(g["clearance_m"], g["closest"])]
                  for m, g in long.groupby("m", sort=True)} if "clearance_m" in long.columns else None)
    ot = study.problem("ot")
    cell = (cell_notes(robot, hanging=ot.hang_offset) + test_pose_note(robot, ot, study.test_pose)  # as `design`
            if robot.cell is not None else [])                                                      # says them
    contact = cell + [
        n for m, pairs in (clearance or {}).items()
        for n in contact_note(np.array([c for c, _ in pairs]), [nm for _, nm in pairs], f"the plan of M = {m}")]
    weak = [f"the plan of M = {int(row['m'])}: {n}" for row in versus_m.to_dict("records")  # as `design` says them
            for n in weak_compliance_notes(robot, np.array([row[c] for c in robot.joint_columns("E_dk")], float))]
    certificates = pd.read_csv(paths["studycert"], keep_default_na=False, na_values=[""]).to_dict("records")
    return {
        "entry": entry, "robot": robot_summary(study),
        "test_pose_deg": np.degrees(study.test_pose).round(6).tolist(), "force_N": study.force.tolist(),
        "sigma": study.sigma, "micro": study.sigma < 1e-2,
        "certificate": certificates[0], "certificates": certificates,
        "plans": versus_m.to_dict("records"), "poses": poses, "clearance": clearance, "contact_notes": contact,
        "plan_notes": weak,
        "cell": None if robot.cell is None else robot.cell.describe(),
        "loads": None if study.loads is None else study.loads.spec,
        "candidates": entry.get("candidates"),
        "fig_plan": image_data_uri(paths["studyfigplan"]), "fig_m": image_data_uri(paths["studyfigm"]),
    }


def print_images(svgs) -> dict[str, Path]:
    """The print rendition of every figure: the embedded SVG's data URI (:func:`image_data_uri`) -> the PNG that
    :func:`stiffcal.report.plots.save` wrote beside it (the same figure at :data:`stiffcal.report.plots.PNG_DPI`), for
    :func:`write_pdf`. svgs: paths of SVG figures, each with its ``.png`` beside it."""
    return {image_data_uri(svg): Path(svg).with_suffix(".png") for svg in svgs}


def write_pdf(html_path: str | Path, pdf_path: str | Path, png_for: dict[str, Path] | None = None) -> int:
    """Print the HTML to PDF with WeasyPrint; returns the number of pages.

    png_for: embedded SVG figures (data URI -> PNG file, :func:`print_images`) that the PDF shows as their PNG
    rendition instead: WeasyPrint draws an SVG figure element by element (0.1-1.4 s of CPU each, most of the
    PDF's cost), a PNG it embeds as it is; the HTML keeps the SVG. Any other image is printed as it is.

    Reproducible: the PDF's creation and modification dates, and the time stamps fontTools writes into
    the embedded font subsets, come from ``SOURCE_DATE_EPOCH`` (default: the commit's time), so the same
    HTML gives the same bytes. A missing system library (Pango, HarfBuzz, ...) gives one clear message
    naming it; the HTML report does not need it.
    """
    import datetime
    import os

    from ..provenance import source_date_epoch

    try:
        from weasyprint import HTML, default_url_fetcher
    except OSError as err:  # cffi cannot load Pango/HarfBuzz/etc.; the message names the library
        raise InputError(f"WeasyPrint cannot load a system library it needs ({err}); install it (Debian: "
                         "apt-get install libpango-1.0-0 libpangoft2-1.0-0 libharfbuzz0b) or use the HTML report",
                         source=str(pdf_path)) from None
    epoch = source_date_epoch()
    before = os.environ.get("SOURCE_DATE_EPOCH")
    os.environ["SOURCE_DATE_EPOCH"] = str(epoch)  # read by fontTools when it subsets the fonts
    try:
        png_for = png_for or {}

        def fetch(url: str) -> dict:
            png = png_for.get(url)
            return default_url_fetcher(url) if png is None else {"string": png.read_bytes(), "mime_type": "image/png"}

        doc = HTML(filename=str(html_path), url_fetcher=fetch).render()
        doc.metadata.created = doc.metadata.modified = datetime.datetime.fromtimestamp(
            epoch, datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
        tmp = Path(str(pdf_path) + ".part")
        doc.write_pdf(str(tmp))
    finally:
        if before is None:
            os.environ.pop("SOURCE_DATE_EPOCH")
        else:
            os.environ["SOURCE_DATE_EPOCH"] = before
    tmp.replace(pdf_path)
    return len(doc.pages)
