"""The Taylor method's jet: the vector formulation's Taylor coefficients, as compiled source.

A Taylor step of order P needs the coefficients y_0..y_P of the solution's series at the step's
start. They follow from the right-hand side written as a sequence of elementary operations
(products, squares, a power, a quotient, linear combinations), each with its own recurrence on
coefficients (automatic differentiation in Taylor mode; Hairer-Norsett-Wanner I, II.13; Jorba
and Zou 2005): the k-th coefficient of a product u v is sum_{j<=k} u_j v_{k-j}; of a quotient
c = u / v, (u_k - sum_{j=1..k} v_j c_{k-j}) / v_0; of c = u^alpha,
sum_{j<k} (alpha (k - j) - j) u_{k-j} c_j / (k u_0); of a state variable, y_{k+1} = f_k / (k+1).

:func:`jet_source` writes a function ``jet(y, p, T)`` that fills ``T`` (``N_ROWS``, P + 1) with
the coefficients of the state (rows 0-10, the vector formulation's order), of the normal force
N (row 11, coefficients 0..P-1) and |v_P|^2 + Lambda^2 at the start (row 12, column 0), for the
ball on the table with the modified Coulomb law and no viscous part, fully unrolled for one
order (every coefficient a local of its own: the compiled jet is straight-line code, half the
time of loops over the orders in a prototype measured on this machine, 2.3 against 4.6 us at
order 13, at the price of a compile of ~20 s per order). Its sums of products are written for
the path each order waits on (:func:`op_lines`): the terms of the newest coefficient last, the
rest in two chains, each sum's terms in the order their inputs are ready (:func:`by_depth`):
1.2-1.4x the jet's speed in index order (``sums="plain"``; benchmarks/bench_jet_sums.py).

The operations are those of :func:`reference_ode.vector.vector_core` for this contact, with
three identities of the exact solution used to drop work (each holds term by term in the
series, since the series is the exact solution's):

* |q|^2 is constant along the flow (q' = q w / 2 with w pure), so 1/|q|^2 is a number per step;
* the axis k is carried as a jet variable of its own, k' = w x k (the vector kd the rates need
  anyway), instead of being recomputed from q's series (four products and four squares);
* k . (w x k) = 0 and |k| = 1, so the spin-torque part of the rates has no k component
  (``k0 = 0``) and (b x k)_z and (w x kd)_z reduce to n (n k_z - w_z) and n w_z - k_z |w|^2.

With A = C (a sphere's inertia, the Fig. 11 top) the terms in 1/C - 1/A and C - A vanish and are
not written (``symmetric``). tests/reference_ode/test_taylor.py checks the jet against the
compiled right-hand side's repeated derivatives and against heyoka's jet.
"""

from __future__ import annotations

#: Rows of the jet's output: the state (11), then N, then |v_P|^2 + Lambda^2 (its 0th only).
N_ROWS = 13
ROW_N = 11
ROW_U = 12
STATE = ("x", "y", "vx", "vy", "qw", "qx", "qy", "qz", "wx", "wy", "wz")


class _Ops:
    """The operations of a jet system, appended in order."""

    def __init__(self) -> None:
        self.ops: list = []

    def mul(self, n: str, a: str, b: str) -> None:
        """Append n = a * b."""
        self.ops.append((n, "mul", (a, b)))

    def sq(self, n: str, a: str) -> None:
        """Append n = a^2."""
        self.ops.append((n, "sq", (a,)))

    def lin(self, n: str, terms: list, c0: str | None = None) -> None:
        """Append n = sum(coef * u) (+ c0)."""
        self.ops.append((n, "lin", (terms, c0)))


def _spin_and_slip(o: _Ops) -> None:
    """The spin about the axis, kd = w x k, the slip and the friction direction phi."""
    # the spin about the axis and kd = w x k (the axis' rate)
    o.mul("a1", "wx", "kx")
    o.mul("a2", "wy", "ky")
    o.mul("a3", "wz", "kz")
    o.lin("n", [("1.0", "a1"), ("1.0", "a2"), ("1.0", "a3")])
    o.mul("b1", "wy", "kz")
    o.mul("b2", "wz", "ky")
    o.lin("kdx", [("1.0", "b1"), ("-1.0", "b2")])
    o.mul("b3", "wz", "kx")
    o.mul("b4", "wx", "kz")
    o.lin("kdy", [("1.0", "b3"), ("-1.0", "b4")])
    o.mul("b5", "wx", "ky")
    o.mul("b6", "wy", "kx")
    o.lin("kdz", [("1.0", "b5"), ("-1.0", "b6")])
    # the slip v_P = v + w x (a k - R e_z) = v + a kd - R (w_y, -w_x)
    o.lin("vpx", [("1.0", "vx"), ("a", "kdx"), ("-R", "wy")])
    o.lin("vpy", [("1.0", "vy"), ("a", "kdy"), ("R", "wx")])
    o.sq("vpx2", "vpx")
    o.sq("vpy2", "vpy")
    o.lin("u", [("1.0", "vpx2"), ("1.0", "vpy2")], "lam2")
    o.ops.append(("s", "powm", ("u", -0.5, "mu")))  # mu / sqrt(|v_P|^2 + Lambda^2)
    o.mul("c1", "s", "vpx")
    o.mul("c2", "s", "vpy")
    o.lin("phx", [("-1.0", "c1")])
    o.lin("phy", [("-1.0", "c2")])


def _contact_torque(o: _Ops, symmetric: bool) -> tuple[str, str, str, str]:
    """t1 = X_P x (phi, 1) and the angular acceleration per unit N: its names and scale."""
    # t1 = X_P x (phi_x, phi_y, 1), X_P = (a kx, a ky, a kz - R)
    o.mul("d1", "kz", "phy")
    o.lin("t1x", [("a", "ky"), ("-a", "d1"), ("R", "phy")])
    o.mul("d2", "kz", "phx")
    o.lin("t1y", [("a", "d2"), ("-R", "phx"), ("-a", "kx")])
    o.mul("d3", "kx", "phy")
    o.mul("d4", "ky", "phx")
    o.lin("t1z", [("a", "d3"), ("-a", "d4")])
    if symmetric:
        return "t1x", "t1y", "t1z", "iA"
    # k . t1 = R (kx phy - ky phx); alpha = t1 / A + (1/C - 1/A) (k . t1) k
    o.lin("k1", [("dC*R", "d3"), ("-dC*R", "d4")])
    o.mul("e1", "k1", "kx")
    o.lin("ax", [("iA", "t1x"), ("1.0", "e1")])
    o.mul("e2", "k1", "ky")
    o.lin("ay", [("iA", "t1y"), ("1.0", "e2")])
    o.mul("e3", "k1", "kz")
    o.lin("az", [("iA", "t1z"), ("1.0", "e3")])
    return "ax", "ay", "az", "1.0"


def _normal_force(o: _Ops, symmetric: bool) -> None:
    """N = M (g - a ((b x k)_z + (w x kd)_z)) / (1 + M a (alpha x k)_z)."""
    # denominator 1 + M a (alpha x k)_z = 1 + M a (t1x ky - t1y kx) / A
    o.mul("f1", "t1x", "ky")
    o.mul("f2", "t1y", "kx")
    o.lin("den", [("M*a*iA", "f1"), ("-M*a*iA", "f2")], "1.0")
    # N = M (g - a ((b x k)_z + (w x kd)_z)) / den, b = -(C - A) n kd / A
    o.sq("w1", "wx")
    o.sq("w2", "wy")
    o.sq("w3", "wz")
    o.lin("ww", [("1.0", "w1"), ("1.0", "w2"), ("1.0", "w3")])
    o.mul("g3", "n", "wz")
    o.mul("g4", "kz", "ww")
    num = [("-M*a", "g3"), ("M*a", "g4")]
    if not symmetric:
        o.mul("g1", "n", "kz")
        o.lin("t0", [("1.0", "g1"), ("-1.0", "wz")])
        o.mul("g2", "n", "t0")
        num.append(("M*a*iA*(C-A)", "g2"))
    o.lin("num", num, "M*g")
    o.ops.append(("N", "div", ("num", "den")))


def jet_system(symmetric: bool) -> tuple[list, dict]:
    """The operations, in order, and each state variable's rate as a linear combination.

    An operation is (name, kind, args): ``mul`` (u, v), ``sq`` (u,), ``lin`` ([(coef, u)],
    constant added to the 0th coefficient or None), ``powm`` (u, alpha, factor): factor u^alpha,
    ``div`` (u, v). Coefficients are source text in the parameters' names (see :func:`jet_source`).
    """
    o = _Ops()
    _spin_and_slip(o)
    ax, ay, az, a_coef = _contact_torque(o, symmetric)
    _normal_force(o, symmetric)
    o.mul("F1", "N", "phx")
    o.mul("F2", "N", "phy")
    pairs = [("wx", "qx"), ("wy", "qy"), ("wz", "qz"), ("qw", "wx"), ("wy", "qz"), ("wz", "qy"),
             ("qw", "wy"), ("wz", "qx"), ("wx", "qz"), ("qw", "wz"), ("wx", "qy"), ("wy", "qx")]
    for i, (u, v) in enumerate(pairs):
        o.mul(f"h{i}", u, v)
    o.mul("j1", "N", ax)
    o.mul("j2", "N", ay)
    o.mul("j3", "N", az)
    rate = {
        "x": [("1.0", "vx")], "y": [("1.0", "vy")],
        "vx": [("1.0/M", "F1")], "vy": [("1.0/M", "F2")],
        "qw": [("-0.5", "h0"), ("-0.5", "h1"), ("-0.5", "h2")],
        "qx": [("0.5", "h3"), ("0.5", "h4"), ("-0.5", "h5")],
        "qy": [("0.5", "h6"), ("0.5", "h7"), ("-0.5", "h8")],
        "qz": [("0.5", "h9"), ("0.5", "h10"), ("-0.5", "h11")],
        "wx": [(a_coef, "j1")], "wy": [(a_coef, "j2")], "wz": [(a_coef, "j3")],
        "kx": [("1.0", "kdx")], "ky": [("1.0", "kdy")], "kz": [("1.0", "kdz")],
    }
    if not symmetric:
        g0 = "(-iA*(C-A))"
        o.mul("l1", "n", "kdx")
        o.mul("l2", "n", "kdy")
        o.mul("l3", "n", "kdz")
        rate["wx"].append((g0, "l1"))
        rate["wy"].append((g0, "l2"))
        rate["wz"].append((g0, "l3"))
    return o.ops, rate


class Constants:
    """The parameter expressions a jet names once (``K0``, ``K1``, ...), as they are met."""

    def __init__(self) -> None:
        self.names: dict[str, str] = {}

    def scaled(self, coef: str, var: str) -> str:
        """``coef * var`` as source, ``coef`` named by its constant (none for 1.0)."""
        if coef == "1.0":
            return var
        if coef not in self.names:
            self.names[coef] = f"K{len(self.names)}"
        return f"{self.names[coef]}*{var}"

    def times(self, coef: str, factor: float, var: str) -> str:
        """``(coef factor) * var`` as source: the constant's product first, off the path."""
        if coef == "1.0":
            return f"{factor!r}*{var}"
        return f"({self.scaled(coef, repr(factor))})*{var}"


#: How a jet sums its series products (:func:`op_lines`): ``"latency"``, the terms that need the
#: newest coefficient last and the rest in two chains; ``"plain"``, one chain in index order.
SUM_ORDERS = ("latency", "plain")


def _sum(hist: list[str], edge: list[str]) -> str:
    """``hist`` (terms of coefficients already known) then ``edge`` (of the newest), as source.

    The history, when long enough to matter (4 terms or more), is summed in two chains of
    alternate terms, added at the end. Each order's coefficients wait on the last order's
    through every operation in turn, so what a product adds to that path is what follows its
    newest coefficient in its sum: here one or two fused multiply-adds, where one chain in
    index order puts the newest coefficient first and the whole chain after it. The jet is
    compiled with contraction but without reassociation, which would fold the chains back into
    one.
    """
    if len(hist) >= 4:
        h = f"({' + '.join(hist[0::2])}) + ({' + '.join(hist[1::2])})"
    else:
        h = " + ".join(hist)
    if not hist:
        return " + ".join(edge)
    return f"({h}) + {' + '.join(edge)}" if edge else h


def _is_plain(sums: str) -> bool:
    """Whether ``sums`` (:data:`SUM_ORDERS`) is the index order; ValueError if neither."""
    if sums not in SUM_ORDERS:
        raise ValueError(f"expected a sum order of {', '.join(SUM_ORDERS)}, got {sums!r}")
    return sums == "plain"


def op_lines(nm: str, kind: str, args: tuple, k: int, consts: Constants,
             sums: str = "latency") -> list[str]:
    """The statements giving operation ``nm``'s k-th coefficient (:func:`jet_system`).

    ``sums`` is how the sums of products are written (:data:`SUM_ORDERS`): the same terms,
    ``"latency"`` with the newest coefficients' terms last (:func:`_sum`), ``"plain"`` in index
    order (the jet until 2026-11-28, kept as the benchmarks' baseline:
    benchmarks/bench_jet_sums.py, bench_jet_packing.py).
    """
    plain = _is_plain(sums)
    t = f"{nm}_{k}"
    if kind == "mul":
        a, b = args
        if plain or k == 0:
            return [f"{t} = " + " + ".join(f"{a}_{j}*{b}_{k - j}" for j in range(k + 1))]
        hist = [f"{a}_{j}*{b}_{k - j}" for j in range(1, k)]
        return [f"{t} = " + _sum(hist, [f"{a}_0*{b}_{k}", f"{a}_{k}*{b}_0"])]
    if kind == "sq":
        (a,) = args
        if plain or k == 0:
            parts = [f"{a}_{j}*{a}_{k - j}" for j in range((k + 1) // 2)]
        else:
            parts = [_sum([f"{a}_{j}*{a}_{k - j}" for j in range(1, (k + 1) // 2)],
                          [f"{a}_0*{a}_{k}"])]
        e = f"2.0*({' + '.join(parts)})" if parts else ""
        if k % 2 == 0:
            e = (f"{e} + " if e else "") + f"{a}_{k // 2}*{a}_{k // 2}"
        return [f"{t} = {e}"]
    if kind == "lin":
        terms, c0 = args
        e = " + ".join(consts.scaled(c, f"{v}_{k}") for c, v in terms)
        if c0 is not None and k == 0:
            e += f" + {c0}"
        return [f"{t} = {e}"]
    if kind == "powm":
        u, alpha, factor = args
        if k == 0:
            lines = [f"{nm}_inv_u0 = 1.0 / {u}_0",
                     f"{t} = {factor} * math.sqrt({nm}_inv_u0)" if alpha == -0.5
                     else f"{t} = {factor} * {u}_0 ** {alpha!r}"]
            return lines if plain else [*lines, f"{nm}_edge = {alpha!r} * {t} * {nm}_inv_u0"]
        parts = [f"{(alpha * (k - j) - j) / k!r}*{u}_{k - j}*{nm}_{j}" for j in range(k)]
        if plain:
            return [f"{t} = ({' + '.join(parts)}) * {nm}_inv_u0"]
        # the newest term's factor alpha c_0 / u_0 is a number per step (``_edge``)
        edge = f"{u}_{k}*{nm}_edge"
        return [f"{t} = ({_sum(parts[1:], [])}) * {nm}_inv_u0 + {edge}" if k > 1
                else f"{t} = {edge}"]
    if kind == "div":
        u, v = args
        if k == 0:
            lines = [f"{nm}_inv_v0 = 1.0 / {v}_0", f"{t} = {u}_0 * {nm}_inv_v0"]
            return lines if plain else [*lines, f"{nm}_edge = {t} * {nm}_inv_v0"]
        parts = [f"{v}_{j}*{nm}_{k - j}" for j in range(1, k + 1)]
        if plain:
            return [f"{t} = ({u}_{k} - ({' + '.join(parts)})) * {nm}_inv_v0"]
        # c_k = u_k / v_0 - (history) / v_0 - v_k (c_0 / v_0): one operation after v_k
        hist = f" - ({_sum(parts[:-1], [])}) * {nm}_inv_v0" if k > 1 else ""
        return [f"{t} = {u}_{k} * {nm}_inv_v0{hist} - {v}_{k}*{nm}_edge"]
    raise ValueError(f"unknown operation kind {kind!r}")


def rate_line(v: str, k: int, rate: dict, consts: Constants, sums: str = "latency") -> str:
    """The statement giving jet variable ``v``'s (k+1)-th coefficient from the k-th rates.

    ``sums`` as :func:`op_lines`': ``"latency"`` scales each term by its constant over k + 1
    (a number per order, off the path), ``"plain"`` scales the sum.
    """
    if _is_plain(sums):
        e = " + ".join(consts.scaled(c, f"{w}_{k}") for c, w in rate[v])
        return f"{v}_{k + 1} = ({e}) * {1.0 / (k + 1)!r}"
    return f"{v}_{k + 1} = " + " + ".join(consts.times(c, 1.0 / (k + 1), f"{w}_{k}")
                                          for c, w in rate[v])


#: The jet variables: the state and the axis k (carried as its own, k' = w x k).
JET_VARS = (*STATE, "kx", "ky", "kz")


def jet_head(signature: str, consts: Constants) -> list[str]:
    """The function's first lines.

    ``def signature:``, the parameters, the named constants and the 0th coefficients of the jet
    variables.
    """
    head = [f"def {signature}:",
            "    R = p[P_R]; a = p[P_A_OFF]; M = p[P_M]; A = p[P_IA]; C = p[P_IC]; g = p[P_G]",
            "    mu = p[P_MU]; lam = p[P_LAM]",
            "    iA = 1.0 / A; dC = 1.0 / C - iA; lam2 = lam * lam",
            "    inv = 1.0 / (y[4] * y[4] + y[5] * y[5] + y[6] * y[6] + y[7] * y[7])"]
    head += [f"    {kn} = {c}" for c, kn in consts.names.items()]
    head += [f"    {v}_0 = y[{i}]" for i, v in enumerate(STATE)]
    head += ["    kx_0 = 2.0 * (qx_0 * qz_0 + qw_0 * qy_0) * inv",
             "    ky_0 = 2.0 * (qy_0 * qz_0 - qw_0 * qx_0) * inv",
             "    kz_0 = (qw_0 * qw_0 - qx_0 * qx_0 - qy_0 * qy_0 + qz_0 * qz_0) * inv"]
    return head


def jet_tail(order: int) -> list[str]:
    """The function's last lines: the coefficients into ``T``."""
    tail = [f"    T[{i}, {k}] = {v}_{k}" for k in range(order + 1) for i, v in enumerate(STATE)]
    tail += [f"    T[{ROW_N}, {k}] = N_{k}" for k in range(order)]
    tail += [f"    T[{ROW_N}, {order}] = 0.0", f"    T[{ROW_U}, 0] = u_0"]
    return tail


def by_depth(ops: list, rate: dict) -> tuple[list, dict]:
    """The same operations with each sum's terms in the order their inputs are ready.

    Within one order the jet variables' coefficients are known first and each operation's
    come after its inputs' (its depth: a product or a power about two operations on the path,
    a linear combination one). A linear combination or a rate then adds its terms earliest
    first, so that the latest input's is the last operation; a product takes its later input
    first (``op_lines`` writes ``a_k b_0`` last). Measured 1.03-1.09x the jet in written order
    (orders 7-12, /tmp prototype, 2026-11-28).
    """
    depth = dict.fromkeys(JET_VARS, 0)
    out = []
    for nm, kind, args in ops:
        if kind == "mul":
            a, b = args
            if depth[b] > depth[a]:
                a, b = b, a
            depth[nm] = depth[a] + 2
            out.append((nm, kind, (a, b)))
            continue
        if kind == "lin":
            terms, c0 = args
            terms = sorted(terms, key=lambda t: depth[t[1]])
            depth[nm] = max(depth[v] for _, v in terms) + 1
            out.append((nm, kind, (terms, c0)))
            continue
        depth[nm] = max(depth[v] for v in args if isinstance(v, str) and v in depth) + 2
        out.append((nm, kind, args))
    return out, {v: sorted(terms, key=lambda t: depth[t[1]]) for v, terms in rate.items()}


def jet_source(order: int, symmetric: bool, name: str = "jet", sums: str = "latency") -> str:
    """Python source of ``name(y, p, T)``: the jet of order ``order``, fully unrolled.

    ``y`` is a vector state (11), ``p`` the packed parameters (:mod:`.params_array`), ``T`` an
    (``N_ROWS``, order + 1) array receiving the coefficients; ``sums`` how the sums of products
    are written (:func:`op_lines`).
    """
    ops, rate = jet_system(symmetric)
    if sums == "latency":
        ops, rate = by_depth(ops, rate)
    consts = Constants()
    body: list[str] = []
    for k in range(order):
        for nm, kind, args in ops:
            body += op_lines(nm, kind, args, k, consts, sums)
        body += [rate_line(v, k, rate, consts, sums) for v in JET_VARS]
    return "\n".join(jet_head(f"{name}(y, p, T)", consts) + ["    " + b for b in body]
                     + jet_tail(order)) + "\n"
