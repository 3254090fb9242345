"""calibrate and its automatic choices: parameters, cause, diagnosis, the delivered fit's weights, the
residual verdict.
"""
