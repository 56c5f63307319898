"""One verdict per study, its meaning and error rate, and the exit code CI gates on.

The verdict is the paired test (mahalanobis.paired_test); the Mahalanobis distance of the
model from the experiments (eq. 41, mahalanobis.verdict) is reported under it as the size of
the discrepancy against the test-to-test scatter, not as a second verdict: a model can sit well
inside that scatter and still be wrong (its power against the report's effects is near zero,
gateway/docs/validate-error-rates.md).
"""
from __future__ import annotations

import math
from typing import Any

from dynval.validate.mahalanobis import PairedTest

# 2 (bad input), 3 (internal error), 64 (usage), 130, 141: every command's (dynval.cli);
# INCONCLUSIVE is 4 so that CI can tell it from a crash
EXIT = {"PASS": 0, "FAIL": 1, "INCONCLUSIVE": 4}
EXIT_MEANING = {"PASS": "no evidence against the model", "FAIL": "the model is rejected",
                "INCONCLUSIVE": "no verdict could be reached"}

ROLE_PAIRED = ("the verdict: do the measured features differ from the model's, driven by each "
               "test's own measured input and carrying the same sensor noise, by more than "
               "the noise explains? An exactly right model is rejected in {alpha:g} % of the "
               "studies")
ROLE_MAHALANOBIS = ("the size: how far the model's features lie from the experiments, in "
                    "units of the test-to-test scatter (report eq. 39-41); not a test (a wrong "
                    "model can sit inside the scatter the forces' randomness makes)")


def decide(paired: PairedTest, mahalanobis: dict[str, Any]) -> dict[str, Any]:
    """The study's verdict from the paired test, with the evidence and what it means."""
    lvl = paired.level
    alpha = 100 * (1 - lvl)
    if paired.reject is None:
        word = "INCONCLUSIVE"
        meaning = f"no paired test could be made: {paired.note}"
    elif paired.reject:
        word = "FAIL"
        meaning = (f"the model is rejected at the {alpha:g} % level: p = {paired.p_value:.3g} "
                   f"< {1 - lvl:g}, the measured features differ from the model's by more than "
                   "the sensor noise explains (a right model is rejected this way in "
                   f"{alpha:g} % of studies)")
    else:
        word = "PASS"
        meaning = (f"no evidence against the model at the {alpha:g} % level: p = "
                   f"{paired.p_value:.3g}; a PASS is only as strong as the features' power "
                   "against the effect in question (dynval validate --rank-against)")
    return {"verdict": word, "exit_code": EXIT[word], "meaning": meaning, "level": lvl,
            "false_rejection_rate": 1 - lvl, "test": paired.method,
            "p_value": paired.p_value,
            "evidence": {"paired": {"role": ROLE_PAIRED.format(alpha=alpha), **paired.summary()},
                         "mahalanobis": {"role": ROLE_MAHALANOBIS, **mahalanobis}}}


def with_checks(v: dict[str, Any], checks: list[dict[str, Any]]) -> dict[str, Any]:
    """The verdict with the linearity / reciprocity checks (validate.checks) as evidence: a
    check the model does not reproduce (it holds on one side, fails on the other) makes it a
    FAIL whatever the paired test says."""
    if not checks:
        return v
    bad = [c["meaning"] for c in checks if not c["consistent"]]
    out = {**v, "evidence": {**v["evidence"], "checks": checks}}
    if bad:
        out.update(verdict="FAIL", exit_code=EXIT["FAIL"],
                   meaning="; ".join(bad) + f" (and the paired test: {v['verdict']})")
    return out


def headline(v: dict[str, Any], model: str) -> str:
    """The one line the CLI prints and the HTML report heads with."""
    return f"{v['verdict']}: model {model}: {v['meaning']}"


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def evidence_lines(v: dict[str, Any]) -> list[str]:
    """The evidence under the verdict, one line each with its role, then how the two read
    together."""
    pt = v["evidence"]["paired"]
    mh = v["evidence"]["mahalanobis"]
    pv = f"{pt['p_value']:.3g}" if _finite(pt["p_value"]) else "-"
    dist = f"{pt['distance']:.4g}" if _finite(pt["distance"]) else "-"
    return [f"  paired test ({pt['test']}, {pt['n']} tests x {pt['p']} features): distance of "
            f"the mean residual {dist}, p = {pv} - {pt['role']}",
            f"  Mahalanobis eq. 41: median D {mh['median_d']:.4g} vs {mh['threshold_kind']} "
            f"95 % limit {mh['threshold']:.4g} ({100 * mh['fraction_within']:.0f} % of tests "
            f"within) - {mh['role']}",
            f"  together: {agreement(v)}",
            *(f"  {c['check']} check @{c['channel']} (z2 of H1 / coherence, limit "
              f"{c['limit']:g}): tests {c['measured']['z2']:.3g} / {c['measured']['z2_coh']:.3g}"
              f", model {c['model']['z2']:.3g} / {c['model']['z2_coh']:.3g} - {c['meaning']}"
              for c in v["evidence"].get("checks", ()))]


def agreement(v: dict[str, Any]) -> str:
    """How the two pieces of evidence read with the verdict, so that a PASS beside a
    distance outside the scatter (or a FAIL inside it) is explained, not left to the reader."""
    mh = v["evidence"]["mahalanobis"]
    word = v["verdict"]
    if not (_finite(mh["median_d"]) and mh["median_d"] >= 0):
        # a quadratic form below zero: the baseline covariance of a few tests is singular
        return (f"the Mahalanobis distance is not usable (median D {mh['median_d']:.4g}: the "
                "baseline covariance of these few tests is singular); "
                + ("no verdict without the paired test" if word == "INCONCLUSIVE" else
                   f"the verdict is the paired test's: {word}"))
    inside = bool(mh["median_d"] <= mh["threshold"])
    where = (f"the model's features lie {'inside' if inside else 'outside'} the test-to-test "
             f"scatter (median D {mh['median_d']:.4g} vs limit {mh['threshold']:.4g})")
    if word == "INCONCLUSIVE":
        return (f"{where}, but the distance is a size, not a test: no verdict without the "
                "paired test")
    if word == "FAIL" and inside:
        return (f"{where}, yet the paired test rejects it: pairing each test with its own input "
                "cancels the forces' randomness that fills the scatter, so it sees a bias the "
                "scatter hides. The verdict is the paired test's")
    if word == "PASS" and not inside:
        return (f"{where}, yet the paired test finds no difference beyond the noise. The verdict "
                "is the paired test's; with few tests or features blind to the effect it has "
                "little power: add tests or check the features (--rank-against) before relying "
                "on this PASS")
    return f"{where}, and the paired test agrees: {word}"
