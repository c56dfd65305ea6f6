#!/usr/bin/env python3
"""The body force that makes a chosen motion an exact solution of plane-strain neo-Hooke
elastodynamics, for massfree's convergence test at finite strain (tests/finite_strain.rs).

    rho u_tt - Div P(F) = b,   F = I + Grad u,
    P = mu (F - F^-T) + lambda ln J F^-T   (2 x 2, plane strain: F_33 = 1)

on the reference unit square, u = 0 on its boundary. Prints the scene's tables: the body
force, the exact displacement, velocity and gradient (massfree's expression syntax: ^ for
powers, log for ln). Needs sympy:  python3 tools/manufactured_finite_strain.py
"""
import sympy as sp

x, y, t = sp.symbols("x y t", real=True)
E, nu, rho = sp.Rational(100), sp.Rational(3, 10), sp.Rational(1)
lam = E * nu / ((1 + nu) * (1 - 2 * nu))
mu = E / (2 * (1 + nu))
a = sp.Rational(1, 10)  # amplitude: strains up to a pi = 0.31
s = sp.sin(sp.pi * x) * sp.sin(sp.pi * y)
u = sp.Matrix([a * s * sp.sin(2 * sp.pi * t), a * s * (1 - sp.cos(2 * sp.pi * t))])
X = [x, y]
F = sp.eye(2) + u.jacobian(X)
J = F.det()
Finv_T = F.inv().T
P = mu * (F - Finv_T) + lam * sp.log(J) * Finv_T
div = sp.Matrix([sum(sp.diff(P[i, j], X[j]) for j in range(2)) for i in range(2)])
b = rho * u.diff(t, 2) - div


def expr(e):
    return str(e).replace("**", "^")


def row(v):
    return "[" + ", ".join('"' + expr(c) + '"' for c in v) + "]"


print("[body_force]")
print("value = " + row(b))
print("[exact]")
print("displacement = " + row(u))
print("velocity = " + row(u.diff(t)))
grad = u.jacobian(X)
print("gradient = [" + ", ".join(row(grad[i, :]) for i in range(2)) + "]")
