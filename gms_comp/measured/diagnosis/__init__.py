"""Diagnosis of measured traces: where the model is wrong, the cause, how sure, what is
ruled out (docs/diagnosis-method.md). :mod:`.run` chains the stages; :mod:`.criterion` is
where an effect is judged; each effect's knowledge is its policy
(:mod:`gms_comp.measured.policies`), its form the runtime's catalogue.
"""
