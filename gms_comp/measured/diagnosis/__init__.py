"""Diagnosis of measured traces: where the model is wrong, the cause, the extended model.

A pipeline of stages, each a module taking one record and returning the next
(:mod:`.run` chains them): :mod:`.prepare` (Trace -> Prepared), :mod:`.baseline`
(-> Baseline, with :mod:`.basis`: the free GMS with its slip level, or a calibrated
table), :mod:`.candidates` and :mod:`.selection` (-> Selection), :mod:`.refit`
(-> Extended), :mod:`.structure` (-> Structure: ``unknown`` or noise), :mod:`.result`
(-> Diagnosis and its JSON). Helpers: :mod:`.design` (bounded least squares, Gram
scoring), :mod:`.motion` (kinematics), :mod:`.encoder` (the position sensor's step),
:mod:`.phases` (residual by motion phase), :mod:`.emps` (the EMPS benchmark's
reference), :mod:`.report` (plots and index.html), :mod:`.config` (the ``[diagnosis]``
section). The effects themselves are the catalogue
in :mod:`gms_comp.runtime.effects`.
"""
