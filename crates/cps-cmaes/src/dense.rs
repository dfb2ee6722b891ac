//! The dense kernels a CMA-ES generation runs, on column-major matrices (nalgebra's
//! storage): the Cholesky factorisation of C, the product of its lower triangular factor
//! with the samples, the lower triangle of the covariance's rank-k update, and C = A Aᵀ.
//!
//! Each is written as updates `y ← y + a x` over contiguous stretches of columns, so the
//! compiler vectorises them; they run in one pulp dispatch, compiled for the machine's
//! widest SIMD (AVX-512, AVX2 or the x86-64 baseline) and chosen at run time. An element
//! is updated by one multiply and one add in the same order whatever the vector width (no
//! fused multiply-add, no reordered sums), so a seeded run gives the same bits on every
//! machine.

use nalgebra::DMatrix;

/// `y ← y + a x`, element by element.
#[inline(always)]
fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

/// `y ← (((y + a₀ x₀) + a₁ x₁) + a₂ x₂) + a₃ x₃`, element by element: four [`axpy`]s in
/// their order, with one load and store of `y`.
#[inline(always)]
fn axpy4(y: &mut [f64], a: [f64; 4], x: [&[f64]; 4]) {
    let len = y.len();
    let (x0, x1, x2, x3) = (&x[0][..len], &x[1][..len], &x[2][..len], &x[3][..len]);
    for i in 0..len {
        let mut v = y[i];
        v += a[0] * x0[i];
        v += a[1] * x1[i];
        v += a[2] * x2[i];
        v += a[3] * x3[i];
        y[i] = v;
    }
}

/// `y ← y + Σₖ a(k) x(k)` for k in `ks`, in that order: [`axpy4`] by fours, then [`axpy`].
#[inline(always)]
fn axpy_all<'a>(
    y: &mut [f64],
    ks: std::ops::Range<usize>,
    a: impl Fn(usize) -> f64,
    x: impl Fn(usize) -> &'a [f64],
) {
    let mut k = ks.start;
    while k + 4 <= ks.end {
        axpy4(
            y,
            [a(k), a(k + 1), a(k + 2), a(k + 3)],
            [x(k), x(k + 1), x(k + 2), x(k + 3)],
        );
        k += 4;
    }
    for k in k..ks.end {
        axpy(y, a(k), x(k));
    }
}

/// Column `k` of a column-major matrix.
pub(crate) fn col(m: &DMatrix<f64>, k: usize) -> &[f64] {
    let n = m.nrows();
    &m.as_slice()[k * n..(k + 1) * n]
}

/// L Lᵀ = A in place: the lower triangle of the square `a` becomes L (left-looking, by
/// columns; the strict upper triangle is left as it was). False, with `a` part-way
/// through, if a pivot is not positive and finite: A is not positive definite.
pub(crate) fn cholesky_lower(a: &mut DMatrix<f64>) -> bool {
    struct Kernel<'a> {
        data: &'a mut [f64],
        n: usize,
    }
    impl pulp::WithSimd for Kernel<'_> {
        type Output = bool;
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) -> bool {
            let n = self.n;
            for j in 0..n {
                let (done, rest) = self.data.split_at_mut(j * n);
                let done: &[f64] = done;
                let column = &mut rest[j..n];
                axpy_all(
                    column,
                    0..j,
                    |k| -done[k * n + j],
                    |k| &done[k * n + j..(k + 1) * n],
                );
                let pivot = column[0];
                if !(pivot > 0.0 && pivot.is_finite()) {
                    return false;
                }
                let d = pivot.sqrt();
                column[0] = d;
                for v in &mut column[1..] {
                    *v /= d;
                }
            }
            true
        }
    }
    let n = a.nrows();
    debug_assert_eq!(n, a.ncols());
    pulp::Arch::new().dispatch(Kernel {
        data: a.as_mut_slice(),
        n,
    })
}

/// `y = L z` for the lower triangle `L` of the square `l` (its upper triangle is not
/// read) and every column of `z`.
pub(crate) fn lower_times(y: &mut DMatrix<f64>, l: &DMatrix<f64>, z: &DMatrix<f64>) {
    struct Kernel<'a> {
        y: &'a mut [f64],
        l: &'a [f64],
        z: &'a [f64],
        n: usize,
    }
    impl pulp::WithSimd for Kernel<'_> {
        type Output = ();
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) {
            let (n, l) = (self.n, self.l);
            for (yk, zk) in self.y.chunks_exact_mut(n).zip(self.z.chunks_exact(n)) {
                yk.fill(0.0);
                // Row block by row block, so that the columns of a block of four start
                // together: y[j..] += Σ L[j.., j+t] z[j+t] over t = 0..4, rows j..j+3
                // of the later columns being zero above their diagonal.
                let mut j = 0;
                while j + 4 <= n {
                    for t in 0..4 {
                        // The triangle's head of the block: rows j..j+4 one column at a time.
                        let c = j + t;
                        axpy(&mut yk[c..j + 4], zk[c], &l[c * n + c..c * n + j + 4]);
                    }
                    axpy4(
                        &mut yk[j + 4..],
                        [zk[j], zk[j + 1], zk[j + 2], zk[j + 3]],
                        std::array::from_fn(|t| &l[(j + t) * n + j + 4..(j + t + 1) * n]),
                    );
                    j += 4;
                }
                for c in j..n {
                    axpy(&mut yk[c..], zk[c], &l[c * n + c..(c + 1) * n]);
                }
            }
        }
    }
    let n = l.nrows();
    debug_assert!(z.nrows() == n && y.nrows() == n && y.ncols() == z.ncols());
    pulp::Arch::new().dispatch(Kernel {
        y: y.as_mut_slice(),
        l: l.as_slice(),
        z: z.as_slice(),
        n,
    })
}

/// The lower triangle of `c` plus `alpha u vᵀ` (`u`, `v`: n × k); the strict upper
/// triangle is not touched.
pub(crate) fn add_lower_product(
    c: &mut DMatrix<f64>,
    alpha: f64,
    u: &DMatrix<f64>,
    v: &DMatrix<f64>,
) {
    struct Kernel<'a> {
        c: &'a mut [f64],
        alpha: f64,
        u: &'a [f64],
        v: &'a [f64],
        n: usize,
        k: usize,
    }
    impl pulp::WithSimd for Kernel<'_> {
        type Output = ();
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) {
            let (n, u, v, alpha) = (self.n, self.u, self.v, self.alpha);
            for (j, cj) in self.c.chunks_exact_mut(n).enumerate() {
                axpy_all(
                    &mut cj[j..],
                    0..self.k,
                    |r| alpha * v[r * n + j],
                    |r| &u[r * n + j..(r + 1) * n],
                );
            }
        }
    }
    let n = c.nrows();
    debug_assert!(u.nrows() == n && v.nrows() == n && u.ncols() == v.ncols());
    pulp::Arch::new().dispatch(Kernel {
        c: c.as_mut_slice(),
        alpha,
        u: u.as_slice(),
        v: v.as_slice(),
        n,
        k: u.ncols(),
    })
}

/// The lower triangle of `c` becomes that of `L Lᵀ`, `L` the lower triangle of `l`
/// (rarely: a repair).
pub(crate) fn lower_gram(c: &mut DMatrix<f64>, l: &DMatrix<f64>) {
    let n = l.nrows();
    let ls = l.as_slice();
    for (j, cj) in c.as_mut_slice().chunks_exact_mut(n).enumerate() {
        cj[j..].fill(0.0);
        for k in 0..=j {
            axpy(&mut cj[j..], ls[k * n + j], &ls[k * n + j..(k + 1) * n]);
        }
    }
}

/// Copies the lower triangle of the square `c` onto its upper one: C stays symmetric bit
/// for bit.
pub(crate) fn mirror_lower(c: &mut DMatrix<f64>) {
    for j in 0..c.ncols() {
        for i in j + 1..c.nrows() {
            c[(j, i)] = c[(i, j)];
        }
    }
}

/// The eigenvalues of the symmetric `c` in ascending order and, in the same order, its
/// unit eigenvectors as the columns of the returned matrix; None if the iteration did not
/// converge or a value is not finite.
pub(crate) fn symmetric_eigen(c: &DMatrix<f64>) -> Option<(Vec<f64>, DMatrix<f64>)> {
    let n = c.nrows();
    let eig = nalgebra::SymmetricEigen::try_new(c.clone(), f64::EPSILON, 0)?;
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let values: Vec<f64> = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let vectors = DMatrix::from_fn(n, n, |i, j| eig.eigenvectors[(i, order[j])]);
    values
        .iter()
        .chain(vectors.iter())
        .all(|v| v.is_finite())
        .then_some((values, vectors))
}
