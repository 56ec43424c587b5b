/* The C kernels of the compiled parts, as the native closed loop (cpp/loop.cpp) calls them: each C extension
 * exports its table of function pointers as a capsule, `fpr._native._<name>._C_API` (CPython's way for one
 * extension to call another: the kernels are compiled once, by the C compiler with the C flags, so the loop runs
 * the very code the parts' Python wrappers run, bit for bit). Plain row-major float64 arrays throughout; each
 * kernel's comment in its source says its arguments. */
#ifndef FPR_KERNELS_H
#define FPR_KERNELS_H

#ifdef __cplusplus
extern "C" {
#endif

/* bumped when a table or a kernel's arguments change: the loop refuses a table of another version */
#define FPR_KERNELS_VERSION 1

typedef struct {
    int version;
    /* alloc.c's tick_kernel: 1 done, 0 the Python path decides, -1 constants or sizes do not fit */
    int (*tick)(const double *m_inv_a, const double *j_f, const double *a_tau, const double *c, int nv,
                const double *f_d, const double *u_a, const double *constants, long constants_len,
                signed char *state, double *z, double *thrust, double *torque, unsigned long long *bits, int *route,
                int *iterations);
    /* alloc.c's inner_kernel: 1 done, 0 a result not finite, -1 constants do not fit */
    int (*inner)(const double *q, const double *v, int n, const double *force, const double *rate,
                 const double *acceleration, const double *constants, long constants_len, double *thrust,
                 double *u_a, double *roll_target, double *pitch);
} FprAllocApi;

typedef struct {
    int version;
    /* attitude.c's post_kernel: 1 done, 0 M_p not positive definite, -1 constants do not fit */
    int (*post)(const double *m_p, const double *nle_p, const double *jacobians, const double *constants,
                long constants_len, double *m_inv_a, double *j_tau, double *j_f, double *a_tau, double *c);
} FprAttitudeApi;

typedef struct {
    int version;
    /* watch.c's screen_kernel: 1 may be lost, 0 not, -1 constants do not fit the state */
    int (*screen)(const double *qc, long nqc, const double *vc, long nvc, const double *q, const double *v, long nq,
                  const double *positions, long nd, double closure_error, const double *planned, long ns,
                  const double *constants, long constants_len);
} FprWatchApi;

#ifdef __cplusplus
}
#endif

#endif
