//! Several dot products with one vector at once, each bit for bit what a lone
//! `v.iter().zip(c).map(|(p, q)| p * q).sum::<f64>()` gives. A dot product summed in order is
//! a chain of adds, each waiting on the last (a few cycles apiece); `L` chains side by side
//! overlap, while each keeps its own order, so results (and everything downstream, such as an
//! identified model or a lockstep run) do not move.

/// The dot products of `v` with each of `cols`, summed in order from `Sum`'s own start.
///
/// ```
/// let v = [1.0, 2.0, 3.0];
/// let [a, b] = evoloop_linalg::dots(&v, [&[1.0, 0.0, 0.0], &[0.5, 0.5, 0.5]]);
/// assert_eq!((a, b), (1.0, 3.0));
/// ```
///
/// # Panics
/// If a column is not as long as `v`.
pub fn dots<const L: usize>(v: &[f64], cols: [&[f64]; L]) -> [f64; L] {
    let start = std::iter::empty::<f64>().sum::<f64>();
    let mut sums = [start; L];
    for c in &cols {
        assert_eq!(c.len(), v.len(), "a column as long as the vector");
    }
    for (i, p) in v.iter().enumerate() {
        for (s, c) in sums.iter_mut().zip(&cols) {
            *s += p * c[i];
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bit for bit a lone iterator sum, also where every product is -0.0 (the sum's start
    /// decides the sign of zero) and over values across many decades.
    #[test]
    fn each_sum_equals_the_iterators_bit_for_bit() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let unit = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            unit * 10f64.powi((state % 17) as i32 - 8)
        };
        let v: Vec<f64> = (0..1001).map(|_| next().abs()).collect();
        let mut cols: Vec<Vec<f64>> = (0..3).map(|_| v.iter().map(|_| next()).collect()).collect();
        cols.push(vec![-0.0; v.len()]);
        let lone = |c: &[f64]| v.iter().zip(c).map(|(p, q)| p * q).sum::<f64>().to_bits();
        let got = dots(&v, std::array::from_fn::<_, 4, _>(|k| &cols[k][..]));
        for (g, c) in got.iter().zip(&cols) {
            assert_eq!(g.to_bits(), lone(c));
        }
    }
}
