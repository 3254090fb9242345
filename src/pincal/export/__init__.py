"""What the user takes away: corrected URDF and sidecar, their reload, UR YAML, compensated commands,
the CSV template.
"""
