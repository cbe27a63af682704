"""Studies built on the core: the paper's section 4 (accuracy), the device-defect study, planning
studies.
"""
