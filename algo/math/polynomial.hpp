#pragma once

namespace epitrack {

/// Real roots of c[4] x^4 + c[3] x^3 + c[2] x^2 + c[1] x + c[0] (degree drops when leading
/// coefficients vanish). Roots come from the eigenvalues of the companion matrix, each polished by
/// Newton steps. Writes up to 4 roots into `roots`, returns how many. Never allocates.
int solveQuarticReal(const double c[5], double roots[4]);

/// Real roots of c[2] x^2 + c[1] x + c[0]; returns how many (0..2), numerically stable form.
int solveQuadraticReal(const double c[3], double roots[2]);

}  // namespace epitrack
