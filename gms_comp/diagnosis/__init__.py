"""Diagnosis of measured traces: where the model is wrong, the cause, the extended model.

Modules: :mod:`.motion` (kinematics, benchmark signal processing), :mod:`.emps` (the EMPS
benchmark's IDIM-LS reference), :mod:`.baseline` (calibrated GMS), :mod:`.phases`
(residual by motion phase), :mod:`.candidates` (catalogue effects fitted as extensions),
:mod:`.run` (selection on held-out data and the result), :mod:`.report` (plots).
"""
