"""Effects that add a model element (dynval.model.elements): contact, friction,
stick-slip, cubic spring, v|v| damper, a constant force offset. Their parameters carry
the registry's names and units, and their evidence bases are the element's law
evaluated by the core (dv_elem_force_block), never a copy of it."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from dynval import model as mdl
from dynval.discover.effects.base import (
    Candidate,
    EffectType,
    Param,
    States,
    add_element,
    element_param,
    pair_basis,
    pair_label,
    pairs,
    readjust_local,
    relative,
    unit_force,
)
from dynval.model import elements as el

_QUANTILES = (0.6, 0.75, 0.85, 0.9, 0.95, 0.98, 0.99, 0.995, 0.998)


class Contact(EffectType):
    type = "contact"
    stiffens = True
    location_kind = "story"
    nonlinear = True
    simpler = ("cubic_stiffness",)  # a smooth hardening with one parameter for three
    law = ("gap/bumper on the story drift X (report eq. 6-7): s = X - gap (pos side) or "
           "-X - gap (neg); force 0 for s <= 0, kB s^2/(2 delta) for s < delta, kB (s - delta/2) "
           "beyond; both sides: their sum, a clearance closing either way; a dv_model contact "
           "element")

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        # 'both': a clearance (free play, a loose joint) that closes either way, one gap
        return [{**loc, "side": side} for loc in pairs(m.n_dof)
                for side in ("pos", "neg", "both")]

    def label(self, loc: dict[str, Any]) -> str:
        return f"contact, {pair_label(loc)}, {loc['side']} side"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        a, b = cand.location["between"]
        d, _ = relative(st, a, b)
        side = cand.location["side"]
        y = {"pos": d, "neg": -d, "both": np.abs(d)}[side]
        out = []
        for q in _QUANTILES:  # a bilinear contact (delta = 0, kB = 1) at the drift's quantiles
            gap = max(float(np.quantile(y, q)), 0.0)
            g = st.hp(unit_force("contact", d, side=side, gap_m=gap, delta_m=0.0))
            out.append(({"gap_m": gap, "quantile": q}, pair_basis(st, a, b, g)))
        return out

    def motion_scales(self, st: States, cand: Candidate) -> dict[str, float]:
        a, b = cand.location["between"]
        d, _ = relative(st, a, b)
        return {"drift_rms_m": float(np.std(d))}

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        k = max(m.stiffness_n_per_m)
        dscale = float(cand.shape.get("drift_rms_m", 1e-4))
        return [element_param("contact", "gap_m", 0.0, 10 * dscale),
                element_param("contact", "delta_m", 1e-3 * dscale, 10 * dscale, log=True),
                element_param("contact", "kb_n_per_m", 1e-3 * k, 20 * k, log=True,
                              null=0.0)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        ps = self.params(m, cand)
        gap = float(cand.shape.get("gap_m", 0.0))
        dscale = float(cand.shape.get("drift_rms_m", 1e-4))
        kb = float(np.clip(abs(amp), ps[2].lower * 2, ps[2].upper * 0.5))
        return [float(np.clip(gap, 0.0, ps[0].upper * 0.9)), 0.3 * dscale, kb]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        a, b = cand.location["between"]
        return add_element(m, "contact", a, b, values, f"discovered contact {a}-{b}",
                            cand.location["side"])

    # the scan's gaps and transitions (x the drift's RMS) and contact stiffnesses (x the
    # stiffest story's)
    _SCAN_GAPS = (0.0, 0.1, 0.25, 0.5, 1.0, 2.0)
    _SCAN_DELTAS = (0.1, 0.3)
    _SCAN_KB = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0)

    def stuck_starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        """A grid of gaps, transitions and contact stiffnesses. The evidence reads a
        contact's stiffness to first order, and from estimated states it can be far off: a
        stepped sine on a 3-DOF chain seen at DOF 1 and 3 read a contact 12 x too soft at a
        gap 12 x too wide (its simulation 5 x the grid's best error), and the fit from there
        stopped at a bilinear spring (gap 0) with 3 x the true contact's held-out error."""
        d = float(cand.shape.get("drift_rms_m", 1e-4))
        k = max(m.stiffness_n_per_m)
        return [[g * d, dl * d, kb * k] for g in self._SCAN_GAPS for dl in self._SCAN_DELTAS
                for kb in self._SCAN_KB]

    def other_starts(self, m: mdl.Model, cand: Candidate, init: Sequence[float]
                     ) -> list[list[float]]:
        """A soft transition as well: the evidence's bilinear gap (delta = 0) is where a soft
        contact's force has risen halfway, and a fit from a sharp start can stop there (a
        clearance closing both ways: gap +15 %, delta / 8, 3.1 x the ideal; from delta = the
        drift's RMS, the ideal)."""
        gap, delta, kb = (float(v) for v in init)
        d = float(cand.shape.get("drift_rms_m", 0.0))
        return [[max(gap - 0.5 * d, 0.0), d, kb]] if delta < 0.5 * d else []

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        return readjust_local(m, cand.location["between"], band_hz)


class _ElementEffect(EffectType):
    """An effect that is a new model element (a registry type, model/elements.py): its
    evidence basis and its fit both run the core's law."""

    element = ""  # registry type name
    tag = ""  # in the discovered element's name

    @staticmethod
    def _scale(cand: Candidate, default: float) -> float:
        a = abs(float(cand.shape.get("amp", 0.0)))
        return a if a > 0 else default


class _PairElement(_ElementEffect):
    """An element between DOF a and DOF b (a = 0: the ground), at every pair of the model."""

    location_kind = "pair"
    what = ""
    nonlinear = True

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return pairs(m.n_dof)

    def label(self, loc: dict[str, Any]) -> str:
        return f"{self.what}, {pair_label(loc)}"

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        a, b = cand.location["between"]
        return add_element(m, self.element, a, b, values, f"discovered {self.tag} {a}-{b}")

    def readjust(self, m: mdl.Model, cand: Candidate, band_hz: tuple[float, float]
                 ) -> tuple[str, ...]:
        return readjust_local(m, cand.location["between"], band_hz)

    @staticmethod
    def _rel(st: States, cand: Candidate) -> tuple[np.ndarray, np.ndarray]:
        a, b = cand.location["between"]
        return relative(st, a, b)

    def _basis(self, st: States, cand: Candidate, g: np.ndarray) -> np.ndarray:
        a, b = cand.location["between"]
        return pair_basis(st, a, b, st.hp(g))


class _OneCoefficient(_PairElement):
    """A pair element with one coefficient (its amplitude)."""

    default_scale = 1.0

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        c = self._scale(cand, self.default_scale)
        name = el.spec(self.element).params[0].name
        return [element_param(self.element, name, 1e-3 * c, 1e2 * c, log=True, null=0.0)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        return [self._scale(cand, self.default_scale)]

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        x, v = self._rel(st, cand)
        return [({}, self._basis(st, cand, unit_force(self.element, x, v)))]


def rigid_body_like(m: mdl.Model) -> bool:
    """Whether the model has a mode far below the others (a carriage on a guide, a structure
    on rails): there a constant force moves the whole body and shows only through how it
    balances against friction."""
    f = mdl.natural_frequencies(m)
    return bool(f.size > 1 and f[0] < 1e-3 * f[-1])


class _FrictionOffset(_PairElement):
    """Friction laws with a variant that carries a constant force between the same DOFs
    (``offset`` in the location): asymmetric friction, or friction balancing a force offset
    (a drive's bias, a weight component), as a positioning stage has. On a rigid-body-like
    model the offset is not seen on its own (the friction balances it, the residual keeps no
    mean) and the friction alone fits badly: the two are fitted together."""

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        base = pairs(m.n_dof)
        if not rigid_body_like(m):
            return base
        return [*base, *({**loc, "offset": True} for loc in base)]

    def label(self, loc: dict[str, Any]) -> str:
        return super().label(loc) + (", with a force offset" if loc.get("offset") else "")

    def law_params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        raise NotImplementedError

    def law_starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        return [self.initial(m, cand, amp)]

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        ps = self.law_params(m, cand)
        if not cand.location.get("offset"):
            return ps
        span = 2 * ps[0].upper  # the law's force bound
        return [*ps, Param("offset_force_n", "N", -span, span, null=0.0)]

    def starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        extra = [0.0] if cand.location.get("offset") else []
        return [[*s, *extra] for s in self.law_starts(m, cand, amp)]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        n = len(self.law_params(m, cand))
        out = super().apply(m, cand, values[:n])
        if not cand.location.get("offset"):
            return out
        a, b = cand.location["between"]
        return add_element(out, "constant_force", a, b, values[n:],
                            f"discovered force offset {a}-{b}")


# the friction's regularisation reaches this many times the relative velocity's RMS under
# the current model: a joint that never slides acts as a dashpot F / eps (blind sweep case 8:
# 0.91 N to the ground with eps 1e-4 m/s at a DOF moving at 6e-7 m/s RMS, out of reach at the
# old bound 0.5 x: its fit ended at 0.0045 N)
VISCOUS_EPS = 30.0


class Friction(_FrictionOffset):
    tag = "friction"
    type = "friction"
    element = "friction"
    what = "friction"
    law = ("Coulomb friction between DOF a and DOF b (or the ground) on the relative velocity V: "
           "F V / sqrt(V^2 + eps^2) (a dv_model friction element, -> F sign(V))")

    def law_params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        f = self._scale(cand, 1.0)
        vr = float(cand.shape.get("v_rms", 1e-2))
        return [element_param("friction", "force_n", 1e-3 * f, 20 * f, log=True, null=0.0),
                element_param("friction", "v_eps_m_per_s", 1e-3 * vr, VISCOUS_EPS * vr,
                              log=True)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        vr = float(cand.shape.get("v_rms", 1e-2))
        return [max(abs(amp), 1e-3 * self._scale(cand, 1.0) * 2), 0.03 * vr]

    def law_starts(self, m: mdl.Model, cand: Candidate, amp: float) -> list[list[float]]:
        # a sharp and a smooth regularisation (stick-slip data with a presliding range can
        # prefer the smooth one), and one that never slides (VISCOUS_EPS)
        f0, e0 = self.initial(m, cand, amp)
        vr = float(cand.shape.get("v_rms", 1e-2))
        return [[f0, e0], [f0, 10 * e0], [f0, 10 * vr]]

    def motion_scales(self, st: States, cand: Candidate) -> dict[str, float]:
        return {"v_rms": float(np.std(self._rel(st, cand)[1]))}

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        _, v = self._rel(st, cand)
        vs = float(np.std(v)) or 1.0
        # the core's friction law, eps relative to the velocity's STD
        return [({"v_eps_rel": eps},
                 self._basis(st, cand, unit_force("friction", v=v, v_eps_m_per_s=eps * vs)))
                for eps in (0.02, 0.1)]


class StickSlipFriction(_FrictionOffset):
    tag = "stick-slip"
    type = "stick_slip"
    stiffens = True
    element = "stick_slip"
    what = "stick-slip friction"
    law = ("stick-slip (Jenkins) friction between DOF a and DOF b (or the ground): a stick "
           "spring F/z in series with a slider at F, rate-independent hysteresis (a dv_model "
           "stick_slip element)")
    _FR = (0.003, 0.01, 0.05, 0.15, 0.4, 0.8)

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        x, _ = self._rel(st, cand)
        xs = float(np.std(x)) or 1.0
        # the core's stick-slip law (from the virgin state) over slip_m
        return [({"slip_m": f * xs, "x_rms": xs},
                 self._basis(st, cand, unit_force("stick_slip", x, slip_m=f * xs)))
                for f in self._FR]

    def law_params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        f = self._scale(cand, 1.0)
        xs = float(cand.shape.get("x_rms", 1e-4))
        return [element_param("stick_slip", "force_n", 1e-3 * f, 20 * f, log=True,
                              null=0.0),
                element_param("stick_slip", "slip_m", 1e-4 * xs, 2.0 * xs, log=True)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        xs = float(cand.shape.get("x_rms", 1e-4))
        return [max(abs(amp), 2e-3 * self._scale(cand, 1.0)),
                float(cand.shape.get("slip_m", 0.05 * xs))]


class CubicStiffness(_OneCoefficient):
    """Hardening (k3 > 0) or softening (k3 < 0): fitted on a signed log scale from the sign
    the evidence gives (the basis's coefficient with the linear nuisances taken out), which
    the fit may cross when the evidence is weak."""

    tag = "cubic"
    type = "cubic_stiffness"
    stiffens = True
    element = "cubic_spring"
    what = "cubic stiffness"
    default_scale = 1e12
    law = ("cubic spring between two DOFs: k3 X^3, k3 > 0 hardening, k3 < 0 softening (a "
           "dv_model cubic_spring element)")

    @staticmethod
    def _sign(cand: Candidate) -> float:
        s = float(cand.shape.get("sign", cand.shape.get("amp", 1.0)) or 1.0)
        return 1.0 if s > 0 else -1.0

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        c = self._scale(cand, self.default_scale)
        # up to 1e4 x: a view that does not see every DOF (the output view) can put the
        # coefficient far under the true one (blind sweep case 15: 250 x)
        return [element_param(self.element, "k3_n_per_m3", 1e-3 * c, 1e4 * c, signed=True,
                              null=0.0)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        return [self._sign(cand) * self._scale(cand, self.default_scale)]

    def other_starts(self, m: mdl.Model, cand: Candidate, init: Sequence[float]
                     ) -> list[list[float]]:
        """A tenth of the evidence's coefficient as well: a best-linear declared stiffness
        holds part of the hardening already, and the full coefficient on top of it counts
        that part twice; under a sweep the doubled hardening's jumps put the fit in another
        basin (blind sweep case 3: normalised SSE 4.45 from the evidence's 1.4e13 N/m^3,
        0.75-1.09 from 1/3 to 1/100 of it)."""
        return [[0.1 * float(init[0])]]


class VelocitySquaredDamping(_OneCoefficient):
    tag = "v|v| damper"
    type = "vv_damping"
    element = "vv_damper"
    what = "velocity-squared damping"
    default_scale = 1e3
    law = "quadratic damper between two DOFs: c2 V |V| (a dv_model vv_damper)"


class ForceOffset(_ElementEffect):
    type = "force_offset"
    element = "constant_force"
    location_kind = "dof"
    law = ("a constant force F at DOF j whatever the motion: a preload, a weight component on "
           "an incline, a force transducer's bias at the input DOF (a dv_model constant_force "
           "element from the ground)")

    def locations(self, m: mdl.Model) -> list[dict[str, Any]]:
        return [{"dof": j, "between": [0, j]} for j in range(1, m.n_dof + 1)]

    def label(self, loc: dict[str, Any]) -> str:
        return f"force offset, DOF {loc['dof']}"

    def basis(self, st: States, cand: Candidate) -> list[tuple[dict[str, float], np.ndarray]]:
        return []  # the views high-pass a constant away: judged by probe()

    def probe(self, m: mdl.Model, cand: Candidate, amount: float) -> mdl.Model | None:
        return self.apply(m, cand, [amount])

    def params(self, m: mdl.Model, cand: Candidate) -> list[Param]:
        span = 10 * abs(float(cand.shape.get("amp", 0.0))) + float(cand.shape.get("probe", 1.0))
        return [element_param("constant_force", "force_n", -span, span, null=0.0)]

    def initial(self, m: mdl.Model, cand: Candidate, amp: float) -> list[float]:
        return [amp]

    def apply(self, m: mdl.Model, cand: Candidate, values: Sequence[float]) -> mdl.Model:
        j = cand.location["dof"]
        return add_element(m, "constant_force", 0, j, values, f"discovered force offset {j}")
