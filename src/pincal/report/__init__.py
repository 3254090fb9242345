"""What a person reads: the JSON report and its findings, the summary table, the verdict line, the
diagnosis plots.
"""
