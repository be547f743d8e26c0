"""Measured deflections: the CSV contract, the error model of the rows, the catalogue of causes, the analysis (fits,
noise, closed testing, the verdict), the discrimination plan and the calibrated model in use."""
