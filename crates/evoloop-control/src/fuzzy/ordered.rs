//! The order-preserving map of eqs. 20-22: genes u_i in (0, 1) become MF centres
//! m_0 < m_1 < ... < m_{L-1} inside their bounds L_i < m_i < U_i, so the GA can never reorder a
//! linguistic variable's labels (which would change the rule base) and needs no penalty.
//!
//! m_i = L_i + (U_i - L_i) f_i with f_0 = u_0 and f_i = 1 + (u_0 - 1) prod_{j=1..i} u_j: the
//! fractions f_i increase strictly towards 1, so the centres are ordered whenever the bounds are
//! non-decreasing in i (the paper's eq. 22 prints the first term as "+ A_0", read as L_0).

/// Centres from genes; `lower`/`upper` the bounds per centre (non-decreasing).
pub fn centres(u: &[f64], lower: &[f64], upper: &[f64], out: &mut [f64]) {
    let mut p = 1.0;
    for i in 0..u.len() {
        let f = if i == 0 {
            u[0]
        } else {
            p *= u[i];
            1.0 + (u[0] - 1.0) * p
        };
        out[i] = lower[i] + (upper[i] - lower[i]) * f;
    }
}

/// Genes from strictly ordered centres strictly inside their bounds (the inverse map), for
/// seeding a GA with user-specified sets. None when the centres are not ordered or not inside.
pub fn genes(m: &[f64], lower: &[f64], upper: &[f64]) -> Option<Vec<f64>> {
    let f: Vec<f64> = (0..m.len())
        .map(|i| (m[i] - lower[i]) / (upper[i] - lower[i]))
        .collect();
    if f.iter().any(|x| !(*x > 0.0 && *x < 1.0)) || f.windows(2).any(|w| w[1] <= w[0]) {
        return None;
    }
    let mut u = vec![f[0]];
    for i in 1..m.len() {
        // (1 - f_i) = (1 - u_0) prod_{j<=i} u_j  =>  u_i = (1 - f_i) / (1 - f_{i-1}).
        u.push((1.0 - f[i]) / (1.0 - f[i - 1]));
    }
    Some(u)
}
