"""The HTML report and its PDF (:mod:`stiffcal.report.html`) and the paper's figures
(:mod:`stiffcal.report.plots`)."""
