//! Least squares for tall, skinny real problems (hundreds of thousands of rows, a handful of
//! unknowns) without forming the design matrix: rows are pushed as they are computed and folded
//! into the triangular factor of a Householder QR, chunk by chunk.
//!
//! For the augmented matrix `A = [X y]` (m × (u+1)) the fold keeps `R` ((u+1) × (u+1), upper
//! triangular) with `A = Q R` for some orthogonal `Q`. Stacking two factors and factoring again
//! gives the factor of the stacked rows, so chunks computed apart (on other threads) merge exactly
//! as their rows would have. From `R = [[R_x, z], [0, ρ]]`:
//!
//! * the solution: `R_x θ = z` (backward substitution);
//! * the residual norm: `|y - X θ| = |ρ|`;
//! * the singular values of `X` are those of `R_x` (rank as `numpy.linalg.lstsq` counts it);
//! * the leverage of row `x_i`: `h_i = x_iᵀ (XᵀX)⁻¹ x_i = |R_x⁻ᵀ x_i|²`;
//! * the HC3 covariance (MacKinnon & White 1985):
//!   `(XᵀX)⁻¹ (Σ_i x_i x_iᵀ r_i² / (1 - h_i)²) (XᵀX)⁻¹` with `(XᵀX)⁻¹ = R_x⁻¹ R_x⁻ᵀ`.
//!
//! QR keeps the accuracy of the data (the normal equations would square the condition number).
//! Values enter as given (no scaling before the fold): sums of squares of magnitudes beyond about
//! 1e±150 overflow or underflow. A caller with such data scales its columns first (SI data of
//! rotating machinery lies many orders of magnitude inside).

use crate::error::CoreError;

/// Most columns of `[X y]` (5 unknowns and the right-hand side).
pub const MAX_COLS: usize = 6;
/// Rows gathered before they are folded into `R`.
const CHUNK_ROWS: usize = 256;

type Square = [[f64; MAX_COLS]; MAX_COLS];

/// Triangular factor of the rows pushed so far (see the module documentation).
#[derive(Clone, Debug)]
pub struct TallQr {
    cols: usize,
    /// upper triangle of R, row-major; entries below the diagonal stay zero
    r: Square,
    /// pending rows, column-major: column j is `buf[j * CHUNK_ROWS..][..fill]`
    buf: Vec<f64>,
    fill: usize,
    rows: usize,
}

impl TallQr {
    /// An empty factor of `cols` columns (`1 ≤ cols ≤ MAX_COLS`; unknowns and right-hand side).
    pub fn new(cols: usize) -> Result<TallQr, CoreError> {
        if cols == 0 || cols > MAX_COLS {
            return Err(CoreError::value("cols", format!("must be 1 to {MAX_COLS}, got {cols}")));
        }
        Ok(TallQr { cols, r: [[0.0; MAX_COLS]; MAX_COLS], buf: vec![0.0; cols * CHUNK_ROWS], fill: 0, rows: 0 })
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Number of rows pushed or folded (merged factors count their rows).
    pub fn rows(&self) -> usize {
        self.rows + self.fill
    }

    /// Append one row (`cols` values; `Err` for another length). Values are not checked; a NaN
    /// spreads to `R`.
    #[inline]
    pub fn push(&mut self, row: &[f64]) -> Result<(), CoreError> {
        if row.len() != self.cols {
            return Err(CoreError::length("row", row.len(), self.cols.to_string()));
        }
        self.push_row(row);
        Ok(())
    }

    #[inline]
    fn push_row(&mut self, row: &[f64]) {
        for (j, &v) in row.iter().enumerate() {
            self.buf[j * CHUNK_ROWS + self.fill] = v;
        }
        self.fill += 1;
        if self.fill == CHUNK_ROWS {
            self.fold();
        }
    }

    /// Append every row of another factor's `R` (the factor of both sets of rows follows).
    pub fn merge(&mut self, mut other: TallQr) -> Result<(), CoreError> {
        if other.cols != self.cols {
            return Err(CoreError::value("other", format!("has {} columns, expected {}", other.cols, self.cols)));
        }
        other.fold();
        let rows = self.rows() + other.rows;
        for i in 0..other.cols {
            let row = other.r[i];
            self.push_row(&row[..self.cols]);
        }
        self.fold();
        self.rows = rows;
        Ok(())
    }

    /// The factor `R` of every row pushed, (cols × cols) row-major upper triangular.
    pub fn factor(&mut self) -> Square {
        self.fold();
        self.r
    }

    /// Fold the pending rows into R.
    fn fold(&mut self) {
        let m = self.fill;
        if m == 0 {
            return;
        }
        let mut buf = std::mem::take(&mut self.buf);
        // the buffer holds cols columns of CHUNK_ROWS rows: always a valid block
        let _ = self.fold_block(&mut buf, CHUNK_ROWS, m);
        self.buf = buf;
        self.fill = 0;
    }

    /// Fold a block of `m` rows B into R, given column-major with leading dimension `ld`
    /// (column j is `block[j * ld..][..m]`); the block is overwritten. QR of [R; B], one
    /// Householder reflection per column: column j of [R; B] below the diagonal is B[:, j] alone
    /// (R is already triangular), so the reflection v = [1; B[:, j] / (α - β)],
    /// β = -sign(α) sqrt(α² + |B[:, j]|²), α = R[j][j], τ = (β - α) / β touches row j of R and
    /// the rows of B only. The rows count towards [`TallQr::rows`].
    #[inline(always)]
    pub fn fold_block(&mut self, block: &mut [f64], ld: usize, m: usize) -> Result<(), CoreError> {
        let n = self.cols;
        check_block(block, ld, m, n)?;
        self.rows += m;
        if m == 0 {
            return Ok(());
        }
        let r = &mut self.r;
        for j in 0..n {
            let (head, tail) = block.split_at_mut(((j + 1) * ld).min(block.len()));
            let bj = &mut head[j * ld..j * ld + m];
            let s2 = dot(bj, bj);
            if s2 == 0.0 {
                continue;
            }
            let alpha = r[j][j];
            let norm = alpha.hypot(s2.sqrt());
            let beta = if alpha >= 0.0 { -norm } else { norm };
            let tau = (beta - alpha) / beta;
            let inv = 1.0 / (alpha - beta);
            for v in bj.iter_mut() {
                *v *= inv;
            }
            r[j][j] = beta;
            for k in j + 1..n {
                let bk = &mut tail[(k - j - 1) * ld..(k - j - 1) * ld + m];
                let d = (r[j][k] + dot(bj, bk)) * tau;
                r[j][k] -= d;
                for (x, &v) in bk.iter_mut().zip(bj.iter()) {
                    *x -= d * v;
                }
            }
        }
        Ok(())
    }
}

/// A column-major block of `cols` columns, `m` rows, leading dimension `ld` fits in `block`.
fn check_block(block: &[f64], ld: usize, m: usize, cols: usize) -> Result<(), CoreError> {
    if m > ld {
        return Err(CoreError::value("m", format!("({m} rows) exceeds the leading dimension {ld}")));
    }
    if cols > 0 && block.len() < (cols - 1) * ld + m {
        return Err(CoreError::length("block", block.len(), format!("at least {} ({cols} columns of leading dimension {ld})", (cols - 1) * ld + m)));
    }
    Ok(())
}

/// Dot product with 32 running sums (four vector registers of eight, so that the additions do
/// not wait on one another); the order is fixed, so results repeat on every SIMD level.
#[inline(always)]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    const N: usize = 32;
    let mut s = [0.0f64; N];
    let (ca, cb) = (a.chunks_exact(N), b.chunks_exact(N));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for l in 0..N {
            s[l] += x[l] * y[l];
        }
    }
    for (l, (x, y)) in ra.iter().zip(rb).enumerate() {
        s[l] += x * y;
    }
    let mut t = [0.0f64; 8];
    for l in 0..8 {
        t[l] = (s[l] + s[l + 8]) + (s[l + 16] + s[l + 24]);
    }
    ((t[0] + t[4]) + (t[1] + t[5])) + ((t[2] + t[6]) + (t[3] + t[7]))
}

/// What a factor of `[X y]` says about the least-squares problem `X θ ≈ y`.
#[derive(Clone, Debug)]
pub struct Solution {
    /// number of unknowns u
    pub unknowns: usize,
    /// singular values of X, largest first
    pub singular: Vec<f64>,
    /// numerical rank (singular values above `eps · max(m, u) · σ_max`, as `numpy.linalg.lstsq`)
    pub rank: usize,
    /// θ (u,); NaN when the rank is below u
    pub theta: Vec<f64>,
    /// |y - X θ|
    pub residual_norm: f64,
    /// R_x⁻¹ (u × u, row-major, upper triangular); NaN when the rank is below u
    pub r_inv: Vec<f64>,
}

impl Solution {
    /// Solve from a factor of `[X y]` with `rows` rows.
    pub fn from_factor(r: &Square, cols: usize, rows: usize) -> Result<Solution, CoreError> {
        if !(2..=MAX_COLS).contains(&cols) {
            return Err(CoreError::value("cols", format!("must be 2 to {MAX_COLS} (unknowns and y), got {cols}")));
        }
        let u = cols - 1;
        let rx = nalgebra::DMatrix::from_fn(u, u, |i, j| if j >= i { r[i][j] } else { 0.0 });
        let mut singular: Vec<f64> = if rx.iter().all(|v| v.is_finite()) {
            rx.clone().singular_values().iter().copied().collect()
        } else {
            vec![f64::NAN; u]
        };
        singular.sort_by(|a, b| b.partial_cmp(a).unwrap_or(std::cmp::Ordering::Equal));
        let smax = singular[0];
        let tol = f64::EPSILON * (rows.max(u) as f64) * smax;
        let rank = singular.iter().filter(|&&s| s > tol).count();
        let mut theta = vec![f64::NAN; u];
        let mut r_inv = vec![f64::NAN; u * u];
        if rank == u {
            for i in (0..u).rev() {
                let mut s = r[i][u];
                for j in i + 1..u {
                    s -= r[i][j] * theta[j];
                }
                theta[i] = s / r[i][i];
            }
            // columns of R_x⁻¹ by backward substitution on unit vectors
            r_inv.iter_mut().for_each(|v| *v = 0.0);
            for c in 0..u {
                for i in (0..=c).rev() {
                    let mut s = if i == c { 1.0 } else { 0.0 };
                    for j in i + 1..=c {
                        s -= r[i][j] * r_inv[j * u + c];
                    }
                    r_inv[i * u + c] = s / r[i][i];
                }
            }
        }
        Ok(Solution { unknowns: u, singular, rank, theta, residual_norm: r[u][u].abs(), r_inv })
    }

    /// (XᵀX)⁻¹ = R_x⁻¹ R_x⁻ᵀ (u × u, row-major).
    pub fn xtx_inv(&self) -> Vec<f64> {
        let u = self.unknowns;
        let mut out = vec![0.0; u * u];
        for i in 0..u {
            for j in 0..u {
                out[i * u + j] = (i.max(j)..u).map(|k| self.r_inv[i * u + k] * self.r_inv[j * u + k]).sum();
            }
        }
        out
    }

    /// The sandwich (XᵀX)⁻¹ meat (XᵀX)⁻¹ of a symmetric `meat` (u × u, row-major).
    pub fn sandwich(&self, meat: &[f64]) -> Vec<f64> {
        let u = self.unknowns;
        let a = self.xtx_inv();
        let mut am = vec![0.0; u * u];
        for i in 0..u {
            for j in 0..u {
                am[i * u + j] = (0..u).map(|k| a[i * u + k] * meat[k * u + j]).sum();
            }
        }
        let mut out = vec![0.0; u * u];
        for i in 0..u {
            for j in 0..u {
                out[i * u + j] = (0..u).map(|k| am[i * u + k] * a[k * u + j]).sum();
            }
        }
        out
    }
}

/// Accumulator of the HC3 meat Σ x xᵀ (r / (1 - h))² and of Σ r², Σ y² over rows, with the
/// leverage clipped as in HC3 practice: 1 - h ≥ 1e-12.
#[derive(Clone, Debug)]
pub struct Hc3Meat {
    u: usize,
    pub meat: Vec<f64>,
    pub rr: f64,
    pub yy: f64,
}

impl Hc3Meat {
    pub fn new(u: usize) -> Hc3Meat {
        Hc3Meat { u, meat: vec![0.0; u * u], rr: 0.0, yy: 0.0 }
    }

    /// Add the rows of a column-major block `[X y]` (u + 1 columns, `m` rows, leading dimension
    /// `ld`): per row r = y - x θ, h = |R_x⁻ᵀ x|², and x xᵀ (r / max(1 - h, 1e-12))² into the
    /// meat. One pass over the block, eight rows at a time in registers (lanes summed at the
    /// end, in a fixed order).
    #[inline(always)]
    pub fn add_block(&mut self, sol: &Solution, block: &[f64], ld: usize, m: usize) -> Result<(), CoreError> {
        let u = self.u;
        if u == 0 || u >= MAX_COLS {
            return Err(CoreError::value("u", format!("must be 1 to {} unknowns, got {u}", MAX_COLS - 1)));
        }
        check_block(block, ld, m, u + 1)?;
        if sol.unknowns != u {
            return Err(CoreError::value("sol", format!("has {} unknowns, expected {u}", sol.unknowns)));
        }
        match u {
            1 => self.add_strips::<1>(sol, block, ld, m),
            2 => self.add_strips::<2>(sol, block, ld, m),
            3 => self.add_strips::<3>(sol, block, ld, m),
            4 => self.add_strips::<4>(sol, block, ld, m),
            _ => self.add_strips::<5>(sol, block, ld, m),
        }
        Ok(())
    }

    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // lane loops over fixed-size arrays, as in lanes.rs
    fn add_strips<const U: usize>(&mut self, sol: &Solution, block: &[f64], ld: usize, m: usize) {
        const W: usize = 8;
        let mut theta = [0.0; U];
        let mut ri = [[0.0; U]; U]; // R_x⁻¹, row-major
        for j in 0..U {
            theta[j] = sol.theta[j];
            for k in 0..U {
                ri[j][k] = sol.r_inv[j * U + k];
            }
        }
        let mut meat = [[[0.0f64; W]; U]; U];
        let (mut rr, mut yy) = ([0.0f64; W], [0.0f64; W]);
        let mut row = 0;
        while row < m {
            let n = W.min(m - row);
            let mut x = [[0.0f64; W]; U];
            let mut y = [0.0f64; W];
            if n == W {
                // fixed-length copies: loads into registers, not calls to memcpy
                for j in 0..U {
                    x[j] = block[j * ld + row..j * ld + row + W].try_into().unwrap_or([0.0; W]);
                }
                y = block[U * ld + row..U * ld + row + W].try_into().unwrap_or([0.0; W]);
            } else {
                for l in 0..n {
                    for j in 0..U {
                        x[j][l] = block[j * ld + row + l];
                    }
                    y[l] = block[U * ld + row + l];
                }
            }
            let mut r = y;
            for j in 0..U {
                for l in 0..W {
                    r[l] -= theta[j] * x[j][l];
                }
            }
            let mut h = [0.0f64; W];
            for k in 0..U {
                let mut z = [0.0f64; W];
                for j in 0..=k {
                    for l in 0..W {
                        z[l] += ri[j][k] * x[j][l];
                    }
                }
                for l in 0..W {
                    h[l] += z[l] * z[l];
                }
            }
            let mut w2 = [0.0f64; W];
            for l in 0..W {
                let one_h = 1.0 - h[l];
                let w = r[l] / if one_h > 1e-12 { one_h } else { 1e-12 };
                w2[l] = w * w;
            }
            for i in 0..U {
                for j in i..U {
                    for l in 0..W {
                        meat[i][j][l] += w2[l] * x[i][l] * x[j][l];
                    }
                }
            }
            for l in 0..W {
                rr[l] += r[l] * r[l];
                yy[l] += y[l] * y[l];
            }
            row += n;
        }
        let sum = |v: &[f64; W]| ((v[0] + v[4]) + (v[1] + v[5])) + ((v[2] + v[6]) + (v[3] + v[7]));
        for i in 0..U {
            for j in i..U {
                self.meat[i * U + j] += sum(&meat[i][j]);
            }
        }
        self.rr += sum(&rr);
        self.yy += sum(&yy);
    }

    /// Add another accumulator's sums.
    pub fn merge(&mut self, other: &Hc3Meat) {
        for (a, b) in self.meat.iter_mut().zip(&other.meat) {
            *a += b;
        }
        self.rr += other.rr;
        self.yy += other.yy;
    }

    /// The symmetric meat (u × u, row-major, both triangles).
    pub fn symmetric(&self) -> Vec<f64> {
        let u = self.u;
        let mut m = self.meat.clone();
        for i in 0..u {
            for j in 0..i {
                m[i * u + j] = m[j * u + i];
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Normal-equations reference on a well-conditioned problem.
    fn normal_solve(x: &[Vec<f64>], y: &[f64]) -> Vec<f64> {
        let u = x[0].len();
        let mut g = nalgebra::DMatrix::<f64>::zeros(u, u);
        let mut b = nalgebra::DVector::<f64>::zeros(u);
        for (row, &yi) in x.iter().zip(y) {
            for i in 0..u {
                b[i] += row[i] * yi;
                for j in 0..u {
                    g[(i, j)] += row[i] * row[j];
                }
            }
        }
        g.lu().solve(&b).unwrap().iter().copied().collect()
    }

    #[test]
    fn solves_a_known_problem_and_merges_in_any_split() {
        let m = 1000;
        let theta = [1.5, -2.0, 0.25];
        let mut rows = Vec::new();
        let mut ys = Vec::new();
        for i in 0..m {
            let t = i as f64 / m as f64;
            let row = vec![1.0, t, (7.0 * t).sin()];
            let noise = 1e-3 * ((i * 7919 % 101) as f64 / 101.0 - 0.5);
            ys.push(row.iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>() + noise);
            rows.push(row);
        }
        let reference = normal_solve(&rows, &ys);
        for split in [1, 255, 256, 257, 999] {
            let mut a = TallQr::new(4).unwrap();
            let mut b = TallQr::new(4).unwrap();
            for (i, (row, &y)) in rows.iter().zip(&ys).enumerate() {
                let full = [row[0], row[1], row[2], y];
                if i < split { a.push(&full).unwrap() } else { b.push(&full).unwrap() }
            }
            a.merge(b).unwrap();
            assert_eq!(a.rows(), m);
            let sol = Solution::from_factor(&a.factor(), 4, m).unwrap();
            assert_eq!(sol.rank, 3);
            for (t, r) in sol.theta.iter().zip(&reference) {
                assert!((t - r).abs() < 1e-10, "{t} vs {r}");
            }
            let rr: f64 = rows.iter().zip(&ys).map(|(row, y)| {
                let f: f64 = row.iter().zip(&sol.theta).map(|(a, b)| a * b).sum();
                (y - f).powi(2)
            }).sum();
            assert!((sol.residual_norm - rr.sqrt()).abs() < 1e-12 * (1.0 + rr.sqrt()));
        }
    }

    #[test]
    fn counts_the_rank_of_repeated_columns() {
        let mut a = TallQr::new(4).unwrap();
        for i in 0..300 {
            let t = i as f64;
            a.push(&[t, 2.0 * t, 1.0, t + 1.0]).unwrap();
        }
        let sol = Solution::from_factor(&a.factor(), 4, 300).unwrap();
        assert_eq!(sol.rank, 2);
        assert!(sol.theta.iter().all(|v| v.is_nan()));
    }

    #[test]
    fn rejects_rows_and_unknowns_of_the_wrong_size() {
        let mut a = TallQr::new(3).unwrap();
        assert!(a.push(&[1.0, 2.0]).is_err());
        assert!(a.push(&[1.0, 2.0, 3.0, 4.0]).is_err());
        assert_eq!(a.rows(), 0);
        a.push(&[1.0, 2.0, 3.0]).unwrap();
        a.push(&[0.5, 1.0, 4.0]).unwrap();
        let sol = Solution::from_factor(&a.factor(), 3, 2).unwrap();
        let block = vec![0.0; 6 * 4];
        assert!(Hc3Meat::new(6).add_block(&sol, &block, 4, 4).is_err());
        assert!(Hc3Meat::new(0).add_block(&sol, &block, 4, 4).is_err());
        assert!(Hc3Meat::new(3).add_block(&sol, &block, 4, 4).is_err()); // the solution has 2 unknowns
        assert!(Hc3Meat::new(2).add_block(&sol, &block, 4, 4).is_ok());
    }

    #[test]
    fn rejects_bad_column_counts() {
        assert!(TallQr::new(0).is_err());
        assert!(TallQr::new(MAX_COLS + 1).is_err());
        let r = [[0.0; MAX_COLS]; MAX_COLS];
        assert!(Solution::from_factor(&r, 1, 10).is_err());
        let mut a = TallQr::new(3).unwrap();
        assert!(a.merge(TallQr::new(4).unwrap()).is_err());
    }
}
