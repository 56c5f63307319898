/**
 * @file dv_mat.h
 * @brief Small dense matrices for the model and the observer: product, linear solve,
 *        symmetric eigen-decomposition (cyclic Jacobi), eigenvalues of a general matrix
 *        (Hessenberg QR) and the matrix exponential
 *        (scaling and squaring with a (6,6) Pade approximant).
 *
 * All matrices are row-major, element (i, j) at data[i * cols + j] (CMSIS
 * arm_matrix_instance_f32). Nothing here allocates: scratch is caller-owned, sized by the
 * DV_MAT_*_WORK_LEN() macros (in elements). These run at init time; their cost is
 * O(n^3) with data-dependent iteration counts (Jacobi sweeps, squarings), which is why the
 * observer's per-step code never calls them.
 */
#ifndef DV_MAT_H
#define DV_MAT_H

#include "dynval/dv_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** @brief A dense row-major matrix view; the data is owned by the caller. */
typedef struct {
    uint16_t rows;   /**< number of rows */
    uint16_t cols;   /**< number of columns */
    dv_real_t *data; /**< rows * cols elements, element (i, j) at data[i * cols + j] */
} dv_mat_t;

/** Scratch for dv_mat_expm() of an n x n matrix, in elements. */
#define DV_MAT_EXPM_WORK_LEN(n) (5u * (n) * (n))

/** Scratch for dv_mat_eig_sym() of an n x n matrix, in elements. */
#define DV_MAT_EIG_WORK_LEN(n) ((n) * (n))

/** Scratch for dv_mat_eig_real() of an n x n matrix, in elements. */
#define DV_MAT_EIGR_WORK_LEN(n) ((n) * (n) + (n))
/** QR iterations per eigenvalue before dv_mat_eig_real() gives up (2-4 is typical). */
#define DV_MAT_QR_MAX_ITER 30u
/** Largest number of Jacobi sweeps before dv_mat_eig_sym() gives up (converges in < 10). */
#define DV_MAT_JACOBI_MAX_SWEEPS 60u

/**
 * @brief c = a * b.
 * @param[in]  a  m x k
 * @param[in]  b  k x n
 * @param[out] c  m x n; must not alias @p a or @p b
 * @retval DV_OK     done
 * @retval DV_EINVAL NULL argument, or the shapes do not agree
 */
dv_status_t dv_mat_mul(const dv_mat_t *a, const dv_mat_t *b, dv_mat_t *c);

/**
 * @brief Solve a x = b in place by Gaussian elimination with partial pivoting.
 * @param[in,out] a  n x n, destroyed (upper-triangular factor on return)
 * @param[in,out] b  n x m right-hand sides, replaced by the solution x
 * @retval DV_OK        solved
 * @retval DV_EINVAL    NULL argument or shapes disagree
 * @retval DV_EUNSTABLE a pivot is zero or below n * eps * max|a| (singular to working
 *                      precision); @p b is then partly overwritten
 */
dv_status_t dv_mat_solve(dv_mat_t *a, dv_mat_t *b);

/**
 * @brief Eigen-decomposition of a symmetric matrix, s = v diag(w) v^T, by cyclic Jacobi.
 *
 * Eigenvalues come out in ascending order, eigenvectors as the columns of @p v, each of
 * unit 2-norm with its largest-magnitude component positive (a deterministic sign).
 * Only the upper triangle of @p s is read.
 * @param[in]  s     n x n symmetric
 * @param[out] w     n eigenvalues, ascending
 * @param[out] v     n x n, column k = eigenvector of w[k]
 * @param[in]  work  scratch of DV_MAT_EIG_WORK_LEN(n) elements
 * @param[in]  len   elements in @p work
 * @retval DV_OK        done
 * @retval DV_EINVAL    NULL argument, non-square or mismatched shapes, n == 0
 * @retval DV_ESIZE     @p len too small
 * @retval DV_ENUMERIC  @p s has a NaN/Inf element
 * @retval DV_EUNSTABLE no convergence in DV_MAT_JACOBI_MAX_SWEEPS sweeps
 */
dv_status_t dv_mat_eig_sym(const dv_mat_t *s, dv_real_t *w, dv_mat_t *v, dv_real_t *work,
                           size_t len);

/**
 * @brief Eigenvalues of a general real matrix: reduction to upper Hessenberg form by
 *        Householder reflections, then the Francis double-shift QR iteration with deflation
 *        (Golub and Van Loan, Alg. 7.4.2 and 7.5.1). A complex conjugate pair comes out as two
 *        consecutive entries, the one with the positive imaginary part first.
 * @param[in]  a     n x n
 * @param[out] wr    n real parts
 * @param[out] wi    n imaginary parts
 * @param[in]  work  scratch of DV_MAT_EIGR_WORK_LEN(n) elements
 * @param[in]  len   elements in @p work
 * @retval DV_OK        done
 * @retval DV_EINVAL    NULL argument, non-square, n == 0
 * @retval DV_ESIZE     @p len too small
 * @retval DV_ENUMERIC  @p a has a NaN/Inf element
 * @retval DV_EUNSTABLE no convergence in DV_MAT_QR_MAX_ITER iterations for an eigenvalue
 */
dv_status_t dv_mat_eig_real(const dv_mat_t *a, dv_real_t *wr, dv_real_t *wi, dv_real_t *work,
                            size_t len);

/**
 * @brief Matrix exponential e = exp(a).
 *
 * Scaling and squaring: a is scaled by 2^-s so that its infinity norm is <= 1/2, the
 * (6,6) diagonal Pade approximant is formed (Golub and Van Loan, Alg. 11.3.1; relative
 * backward error <= 3.4e-16) and squared s times.
 * @param[in]  a     n x n
 * @param[out] e     n x n; may alias @p a
 * @param[in]  work  scratch of DV_MAT_EXPM_WORK_LEN(n) elements
 * @param[in]  len   elements in @p work
 * @retval DV_OK        done
 * @retval DV_EINVAL    NULL argument, non-square or mismatched shapes, n == 0
 * @retval DV_ESIZE     @p len too small
 * @retval DV_ENUMERIC  @p a has a NaN/Inf element, or the norm needs more than 64 squarings
 * @retval DV_EUNSTABLE the Pade denominator is singular, or the result overflowed
 */
dv_status_t dv_mat_expm(const dv_mat_t *a, dv_mat_t *e, dv_real_t *work, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* DV_MAT_H */
