/* The plant's step (fpr/sim/plant.py, Plant._python_steps and, with a wind, Plant._python_wind_step) in C:
 * the same RKMK4 steps of the closed chain's constraint dynamics, without the interpreter and the
 * per-call cost of ~20 small Pinocchio and numpy calls per stage.
 *
 * The multibody algorithms are written here for the joints the models are built of (revolute and prismatic
 * about any axis, free flyer; a composite exported as its sub-joints), on the model's numbers exported once by
 * model_constants (fpr/model/multibody.py; every integer field a whole number in range, the joints' q and v
 * entries not overlapping, else refused):
 *   - nle(q, v) by the recursive Newton-Euler algorithm (gravity as the base's acceleration), bodies' twists
 *     and accelerations in their own frames, Pinocchio's conventions (motion = [linear, angular]);
 *   - M(q) by the composite rigid-body algorithm on world-frame inertias and motion subspaces;
 *   - each 3D loop closure (two points, one on each of two joints, held together: Pinocchio's CONTACT_3D) as
 *     the world-frame rows G a = gamma, gamma = -(classical drift of p1 - p2) - Kp (x1 - x2) - Kd (x1' - x2')
 *     (Baumgarte). Pinocchio writes the same rows in the contact frame (LOCAL), an orthogonal change of rows
 *     that leaves the acceleration unchanged;
 *   - the accelerations of the KKT system by its Schur complement K = G M^-1 G^T and the proximal iterations of
 *     Pinocchio's constraintDynamics ((K + mu I) l_{k+1} = b + mu l_k from l_0 = 0, mu, max_iter and the
 *     accuracies of its ProximalSettings), which makes the redundant rows of a hinge closure harmless;
 *   - the Lie group step: q (+) theta (the free flyer's exp6 through quaternions, first-order renormalised as
 *     Pinocchio does) and dexp^-1_theta(v) by its Bernoulli series v + [theta, v]/2 + B_2k/(2k)! ad^2k v (up to
 *     ad^16: below 1e-17 relative for |theta_angular| <= 0.5 rad, where the series is used; beyond it, the step
 *     is handed back to the Python path).
 * They agree with Pinocchio's to round-off (tests/test_plant_compiled.py).
 *
 * steps(constants, force_map_t, decay, q, v, w, w_command, w_max, dt, steps[, points, forces])
 *   -> (q, v, w, w_cmd, done, status)
 *   w_command is saturated to [0, w_max] first (w_cmd, as Plant.saturate); forces (world axes, one row per point
 *   of the spec `points`, as points() takes it) push on those points (a wind); w_command has w's shape (any,
 *   at most 64 speeds) and force_map_t is (w.size, nv). status 0: all steps done; 1: the state became
 *   non-finite in step done + 1; 2: a matrix was not positive definite in step done + 1 at a finite state (the
 *   integrator failed); 3: step done + 1 turns a free flyer by more than the series covers (the caller runs it
 *   in Python). q, v, w: the state after `done` steps.
 * points(constants, q, spec) -> (positions (n, 3), closure error): world positions of points on joints (spec:
 *   n, then joint, x, y, z per point) and the largest distance between a closure's two points, at q.
 * velocity(constants, spec, q, vc) -> v or None and frame_terms(constants, spec, q, v) -> (M, nle, Jacobians): the
 *   minimal model's measured velocity and attitude terms (see each function).
 * dynamics(constants, q, v, tau) -> a; rigid_terms(constants, q, v) -> (M, nle); integrate(constants, q, theta)
 *   -> q; dexp_inverse(constants, theta, v) -> x (None beyond the series' range): the parts, for the tests.
 * A malformed input (a constants vector or spec that does not fit, a wrong size or shape) raises a ValueError
 * (TypeError for what is not a number); nothing is read out of range.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include <limits.h>
#include <math.h>
#include <string.h>

#include "fpr/model/_dense.h" /* constants_of, cholesky, cholesky_solve */

#define HEADER 11
#define JOINT 32
#define CONSTRAINT 10
#define MAXJ 16  /* joints, the universe included */
#define MAXV 48  /* velocity size */
#define MAXR 12  /* constraint rows (4 point closures) */
#define SERIES_LIMIT 0.5 /* largest |theta_angular| of a free flyer for the dexp^-1 series [rad] */

enum { REVOLUTE = 0, FREEFLYER = 1, PRISMATIC = 2 };

typedef struct {
    double R[9], p[3];
} SE3;

typedef struct {
    int type, parent, iq, iv, nvj;
    double axis[3];
    SE3 placement;
    double mass, lever[3], inertia[9];
} Joint;

typedef struct {
    int j1, j2;
    double p1[3], p2[3], kp, kd;
} Closure;

typedef struct {
    int nj, nq, nv, nc;
    double gravity[3], mu, abs_acc, rel_acc;
    int max_iter;
    const double *armature;
    Joint joints[MAXJ];
    Closure closures[MAXR / 3];
} Model;

/* world forces at points on joints (a wind on the drones' centres): count, per point (joint, x, y, z) in the
 * joint's frame, and the forces (count x 3, world axes) */
typedef struct {
    int count;
    const double *points, *forces;
} Push;

/* ---------------------------------------------------------------- small spatial algebra (row-major 3x3) */
static inline void cross(const double *a, const double *b, double *out)
{
    const double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    out[0] = x, out[1] = y, out[2] = z;
}

static inline void mat_vec(const double *R, const double *x, double *out)
{
    const double a = R[0] * x[0] + R[1] * x[1] + R[2] * x[2], b = R[3] * x[0] + R[4] * x[1] + R[5] * x[2],
                 c = R[6] * x[0] + R[7] * x[1] + R[8] * x[2];
    out[0] = a, out[1] = b, out[2] = c;
}

static inline void mat_t_vec(const double *R, const double *x, double *out)
{
    const double a = R[0] * x[0] + R[3] * x[1] + R[6] * x[2], b = R[1] * x[0] + R[4] * x[1] + R[7] * x[2],
                 c = R[2] * x[0] + R[5] * x[1] + R[8] * x[2];
    out[0] = a, out[1] = b, out[2] = c;
}

static inline void mat_mat(const double *A, const double *B, double *out)
{
    double r[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
    memcpy(out, r, sizeof r);
}

/* out = a * b (placements: out.R = a.R b.R, out.p = a.p + a.R b.p) */
static inline void compose(const SE3 *a, const SE3 *b, SE3 *out)
{
    double t[3];
    mat_vec(a->R, b->p, t);
    mat_mat(a->R, b->R, out->R);
    out->p[0] = a->p[0] + t[0], out->p[1] = a->p[1] + t[1], out->p[2] = a->p[2] + t[2];
}

/* a motion [linear, angular] of the parent frame in the child frame M (M.actInv) */
static inline void act_inv_motion(const SE3 *M, const double *m, double *out)
{
    double t[3];
    cross(M->p, m + 3, t);
    t[0] = m[0] - t[0], t[1] = m[1] - t[1], t[2] = m[2] - t[2];
    mat_t_vec(M->R, t, out);
    mat_t_vec(M->R, m + 3, out + 3);
}

/* a motion of frame M in its parent's (M.act) */
static inline void act_motion(const SE3 *M, const double *m, double *out)
{
    double w[3], t[3];
    mat_vec(M->R, m + 3, w);
    mat_vec(M->R, m, t);
    double c[3];
    cross(M->p, w, c);
    out[0] = t[0] + c[0], out[1] = t[1] + c[1], out[2] = t[2] + c[2];
    out[3] = w[0], out[4] = w[1], out[5] = w[2];
}

/* a force [linear, angular] of frame M in its parent's (M.act) */
static inline void act_force(const SE3 *M, const double *f, double *out)
{
    double l[3], n[3], c[3];
    mat_vec(M->R, f, l);
    mat_vec(M->R, f + 3, n);
    cross(M->p, l, c);
    out[0] = l[0], out[1] = l[1], out[2] = l[2];
    out[3] = n[0] + c[0], out[4] = n[1] + c[1], out[5] = n[2] + c[2];
}

/* motion cross product a x b */
static inline void motion_cross(const double *a, const double *b, double *out)
{
    double l1[3], l2[3], w[3];
    cross(a + 3, b, l1);
    cross(a, b + 3, l2);
    cross(a + 3, b + 3, w);
    out[0] = l1[0] + l2[0], out[1] = l1[1] + l2[1], out[2] = l1[2] + l2[2];
    out[3] = w[0], out[4] = w[1], out[5] = w[2];
}

/* momentum of a body (mass, lever c, rotational inertia I about the centre of mass) moving at v */
static inline void momentum(const Joint *j, const double *v, double *h)
{
    double t[3];
    cross(j->lever, v + 3, t);
    h[0] = j->mass * (v[0] - t[0]), h[1] = j->mass * (v[1] - t[1]), h[2] = j->mass * (v[2] - t[2]);
    mat_vec(j->inertia, v + 3, t);
    double c[3];
    cross(j->lever, h, c);
    h[3] = t[0] + c[0], h[4] = t[1] + c[1], h[5] = t[2] + c[2];
}

/* rotation of a quaternion (x, y, z, w), Eigen's formula */
static inline void quat_matrix(const double *q, double *R)
{
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    const double tx = 2 * x, ty = 2 * y, tz = 2 * z, twx = tx * w, twy = ty * w, twz = tz * w, txx = tx * x,
                 txy = ty * x, txz = tz * x, tyy = ty * y, tyz = tz * y, tzz = tz * z;
    R[0] = 1 - (tyy + tzz), R[1] = txy - twz, R[2] = txz + twy;
    R[3] = txy + twz, R[4] = 1 - (txx + tzz), R[5] = tyz - twx;
    R[6] = txz - twy, R[7] = tyz + twx, R[8] = 1 - (txx + tyy);
}

/* rotation by angle about a unit axis (Rodrigues) */
static inline void axis_matrix(const double *a, double angle, double *R)
{
    const double c = cos(angle), s = sin(angle), k = 1 - c;
    R[0] = c + k * a[0] * a[0], R[1] = k * a[0] * a[1] - s * a[2], R[2] = k * a[0] * a[2] + s * a[1];
    R[3] = k * a[1] * a[0] + s * a[2], R[4] = c + k * a[1] * a[1], R[5] = k * a[1] * a[2] - s * a[0];
    R[6] = k * a[2] * a[0] - s * a[1], R[7] = k * a[2] * a[1] + s * a[0], R[8] = c + k * a[2] * a[2];
}

/* ---------------------------------------------------------------- the model from its constants */
/* *out = x when x is a whole number in [lo, hi], checked on the double (casting NaN or a double beyond int's
 * range is undefined: INT_MIN on x86); 0 otherwise */
static inline int whole(double x, int lo, int hi, int *out)
{
    if (!(x >= lo && x <= hi) || x != floor(x)) return 0;
    *out = (int)x;
    return 1;
}

static int parse(const double *k, npy_intp len, Model *m)
{
    if (len < HEADER || !whole(k[0], 1, MAXJ, &m->nj) || !whole(k[2], 1, MAXV, &m->nv)
        || !whole(k[1], m->nv, 2 * MAXV, &m->nq) || !whole(k[3], 0, MAXR / 3, &m->nc)
        || len != HEADER + m->nv + JOINT * (m->nj - 1) + CONSTRAINT * m->nc)
        return 0;
    memcpy(m->gravity, k + 4, sizeof m->gravity);
    m->mu = k[7], m->abs_acc = k[9], m->rel_acc = k[10];
    if (!(m->mu > 0) || !whole(k[8], 1, INT_MAX, &m->max_iter)) return 0;
    m->armature = k + HEADER;
    const double *c = k + HEADER + m->nv;
    int nq = 0, nv = 0;
    unsigned char taken_q[2 * MAXV] = {0}, taken_v[MAXV] = {0};  /* the joints' q and v must not overlap */
    for (int i = 1; i < m->nj; i++, c += JOINT) {
        Joint *j = &m->joints[i];
        if (!whole(c[0], REVOLUTE, PRISMATIC, &j->type) || !whole(c[1], 0, i - 1, &j->parent)) return 0;
        j->nvj = j->type == FREEFLYER ? 6 : 1;
        const int nqj = j->type == FREEFLYER ? 7 : 1;
        if (!whole(c[2], 0, m->nq - nqj, &j->iq) || !whole(c[3], 0, m->nv - j->nvj, &j->iv)) return 0;
        for (int e = 0; e < nqj; e++)
            if (taken_q[j->iq + e]++) return 0;
        for (int e = 0; e < j->nvj; e++)
            if (taken_v[j->iv + e]++) return 0;
        nq += nqj, nv += j->nvj;
        memcpy(j->axis, c + 4, sizeof j->axis);
        memcpy(j->placement.R, c + 7, sizeof j->placement.R);
        memcpy(j->placement.p, c + 16, sizeof j->placement.p);
        j->mass = c[19];
        memcpy(j->lever, c + 20, sizeof j->lever);
        memcpy(j->inertia, c + 23, sizeof j->inertia);
    }
    if (nq != m->nq || nv != m->nv) return 0;  /* with no overlap: every q and v belongs to one joint */
    for (int i = 0; i < m->nc; i++, c += CONSTRAINT) {
        Closure *cl = &m->closures[i];
        if (!whole(c[0], 0, m->nj - 1, &cl->j1) || !whole(c[4], 0, m->nj - 1, &cl->j2)) return 0;
        memcpy(cl->p1, c + 1, sizeof cl->p1);
        memcpy(cl->p2, c + 5, sizeof cl->p2);
        cl->kp = c[8], cl->kd = c[9];
    }
    return 1;
}

/* ---------------------------------------------------------------- constrained forward dynamics */
typedef struct {
    SE3 o[MAXJ];            /* world placements */
    double v[MAXJ][6];      /* body twists, own frames */
    double a[MAXJ][6];      /* bias accelerations (gravity as the base's), own frames */
    double cols[MAXV][6];   /* world motion subspace, one column per velocity */
    double Y[MAXJ][36];     /* composite inertias, world frame at the origin, row-major 6x6 */
    double M[MAXV * MAXV], R[MAXV * MAXV], nle[MAXV];
} Work;

/* placement of joint i relative to its parent at q */
static inline void joint_placement(const Joint *j, const double *q, SE3 *out)
{
    SE3 J;
    if (j->type == FREEFLYER) {
        quat_matrix(q + j->iq + 3, J.R);
        memcpy(J.p, q + j->iq, sizeof J.p);
    } else if (j->type == PRISMATIC) {
        memset(J.R, 0, sizeof J.R);
        J.R[0] = J.R[4] = J.R[8] = 1.0;
        J.p[0] = j->axis[0] * q[j->iq], J.p[1] = j->axis[1] * q[j->iq], J.p[2] = j->axis[2] * q[j->iq];
    } else {
        axis_matrix(j->axis, q[j->iq], J.R);
        J.p[0] = J.p[1] = J.p[2] = 0.0;
    }
    compose(&j->placement, &J, out);
}

/* the motion of a one-degree joint at rate qd, in its own frame: [0, axis qd] (revolute), [axis qd, 0] (prismatic) */
static inline void subspace(const Joint *j, double qd, double *out)
{
    const int at = j->type == PRISMATIC ? 0 : 3;
    memset(out, 0, 6 * sizeof(double));
    out[at] = j->axis[0] * qd, out[at + 1] = j->axis[1] * qd, out[at + 2] = j->axis[2] * qd;
}

/* world inertia of joint i's body as a 6x6 matrix at the world origin, added into Y */
static void add_world_inertia(const Joint *j, const SE3 *o, double *Y)
{
    double c[3], Iw[9], t[9];
    mat_vec(o->R, j->lever, c);
    c[0] += o->p[0], c[1] += o->p[1], c[2] += o->p[2];
    mat_mat(o->R, j->inertia, t);
    for (int r = 0; r < 3; r++)  /* Iw = R Ic R^T */
        for (int s = 0; s < 3; s++) Iw[3 * r + s] = t[3 * r] * o->R[3 * s] + t[3 * r + 1] * o->R[3 * s + 1]
                                                 + t[3 * r + 2] * o->R[3 * s + 2];
    const double m = j->mass;
    const double C[9] = {0, -c[2], c[1], c[2], 0, -c[0], -c[1], c[0], 0};
    double CC[9];
    mat_mat(C, C, CC);
    for (int r = 0; r < 3; r++)
        for (int s = 0; s < 3; s++) {
            Y[6 * r + s] += r == s ? m : 0.0;
            Y[6 * r + 3 + s] += -m * C[3 * r + s];
            Y[6 * (3 + r) + s] += m * C[3 * r + s];
            Y[6 * (3 + r) + 3 + s] += Iw[3 * r + s] - m * CC[3 * r + s];
        }
}

/* world placements o (the universe's the identity) and the joints' placements relative to their parents li
 * (NULL: not kept) at q */
static void placements(const Model *m, const double *q, SE3 *o, SE3 *li)
{
    SE3 local;
    memset(&o[0], 0, sizeof o[0]);
    o[0].R[0] = o[0].R[4] = o[0].R[8] = 1.0;
    for (int i = 1; i < m->nj; i++) {
        SE3 *l = li != NULL ? &li[i] : &local;
        joint_placement(&m->joints[i], q, l);
        compose(&o[m->joints[i].parent], l, &o[i]);
    }
}

/* the world motion subspace at placements o: one column per velocity (6 per free flyer) */
static void world_columns(const Model *m, const SE3 *o, double (*cols)[6])
{
    for (int i = 1; i < m->nj; i++) {
        const Joint *j = &m->joints[i];
        if (j->type == FREEFLYER)
            for (int k = 0; k < 6; k++) {
                double e[6] = {0, 0, 0, 0, 0, 0};
                e[k] = 1.0;
                act_motion(&o[i], e, cols[j->iv + k]);
            }
        else {
            double e[6];
            subspace(j, 1.0, e);
            act_motion(&o[i], e, cols[j->iv]);
        }
    }
}

/* out = T x, T (rows x n) row-major */
static void map_rows(const double *T, int rows, int n, const double *x, double *out)
{
    for (int i = 0; i < rows; i++) {
        double t = 0.0;
        for (int k = 0; k < n; k++) t += T[i * n + k] * x[k];
        out[i] = t;
    }
}

/* kinematics, nle (RNEA) and M (CRBA) at (q, v) into w */
static void rigid_terms(const Model *m, const double *q, const double *v, Work *w)
{
    double f[MAXJ][6];
    SE3 li[MAXJ];
    placements(m, q, w->o, li);
    world_columns(m, w->o, w->cols);
    memset(w->v[0], 0, sizeof w->v[0]);
    w->a[0][0] = -m->gravity[0], w->a[0][1] = -m->gravity[1], w->a[0][2] = -m->gravity[2];
    w->a[0][3] = w->a[0][4] = w->a[0][5] = 0.0;
    for (int i = 1; i < m->nj; i++) {
        const Joint *j = &m->joints[i];
        double vj[6], t[6], h[6], c[6];
        if (j->type == FREEFLYER)
            memcpy(vj, v + j->iv, sizeof vj);
        else
            subspace(j, v[j->iv], vj);
        act_inv_motion(&li[i], w->v[j->parent], t);
        for (int k = 0; k < 6; k++) w->v[i][k] = t[k] + vj[k];
        act_inv_motion(&li[i], w->a[j->parent], t);
        motion_cross(w->v[i], vj, c);
        for (int k = 0; k < 6; k++) w->a[i][k] = t[k] + c[k];
        /* f = I a + v x* (I v) */
        momentum(j, w->a[i], f[i]);
        momentum(j, w->v[i], h);
        double l[3], n1[3], n2[3];
        cross(w->v[i] + 3, h, l);
        cross(w->v[i] + 3, h + 3, n1);
        cross(w->v[i], h, n2);
        f[i][0] += l[0], f[i][1] += l[1], f[i][2] += l[2];
        f[i][3] += n1[0] + n2[0], f[i][4] += n1[1] + n2[1], f[i][5] += n1[2] + n2[2];
        memset(w->Y[i], 0, sizeof w->Y[i]);
        add_world_inertia(j, &w->o[i], w->Y[i]);
    }
    const int nv = m->nv;
    for (int i = m->nj - 1; i >= 1; i--) {
        const Joint *j = &m->joints[i];
        if (j->type == FREEFLYER)
            memcpy(w->nle + j->iv, f[i], 6 * sizeof(double));
        else {
            const double *g = j->type == PRISMATIC ? f[i] : f[i] + 3;
            w->nle[j->iv] = j->axis[0] * g[0] + j->axis[1] * g[1] + j->axis[2] * g[2];
        }
        if (j->parent > 0) {
            double t[6];
            act_force(&li[i], f[i], t);
            for (int k = 0; k < 6; k++) f[j->parent][k] += t[k];
            for (int k = 0; k < 36; k++) w->Y[j->parent][k] += w->Y[i][k];
        }
    }
    /* M[cols_a, cols_i] = S_a^T Ycrb_i S_i for every ancestor a of i (and a = i); zero between branches */
    memset(w->M, 0, sizeof(double) * nv * nv);
    for (int i = 1; i < m->nj; i++) {
        const Joint *j = &m->joints[i];
        for (int ci = j->iv; ci < j->iv + j->nvj; ci++) {
            double F[6];
            for (int r = 0; r < 6; r++) {
                double s = 0.0;
                for (int k = 0; k < 6; k++) s += w->Y[i][6 * r + k] * w->cols[ci][k];
                F[r] = s;
            }
            for (int a = i; a > 0; a = m->joints[a].parent) {
                const Joint *ja = &m->joints[a];
                for (int ca = ja->iv; ca < ja->iv + ja->nvj; ca++) {
                    double s = 0.0;
                    for (int k = 0; k < 6; k++) s += w->cols[ca][k] * F[k];
                    w->M[ca * nv + ci] = s;
                    w->M[ci * nv + ca] = s;
                }
            }
        }
    }
    for (int k = 0; k < nv; k++) w->M[k * nv + k] += m->armature[k];
}

/* world position, velocity and classical bias acceleration of the point p of joint i's frame, and its
 * world Jacobian's rows added into G with sign (3 rows, leading dimension nv) */
static void point_terms(const Model *m, const Work *w, int i, const double *p, double sign, double *x,
                        double *xd, double *acc, double *G)
{
    if (i == 0) {  /* fixed in the world: at rest, its acceleration the base's (gravity's offset) */
        memcpy(x, p, 3 * sizeof(double));
        xd[0] = xd[1] = xd[2] = 0.0;
        memcpy(acc, w->a[0], 3 * sizeof(double));
        return;
    }
    const SE3 *o = &w->o[i];
    const double *v = w->v[i], *a = w->a[i];
    double t[3], u[3], c[3], l[3];
    mat_vec(o->R, p, t);
    x[0] = t[0] + o->p[0], x[1] = t[1] + o->p[1], x[2] = t[2] + o->p[2];
    cross(v + 3, p, c);
    u[0] = v[0] + c[0], u[1] = v[1] + c[1], u[2] = v[2] + c[2];
    mat_vec(o->R, u, xd);
    cross(a + 3, p, c);
    cross(v + 3, u, t);
    l[0] = a[0] + c[0] + t[0], l[1] = a[1] + c[1] + t[1], l[2] = a[2] + c[2] + t[2];
    mat_vec(o->R, l, acc);
    const int nv = m->nv;
    for (int s = i; s > 0; s = m->joints[s].parent) {
        const Joint *j = &m->joints[s];
        for (int k = j->iv; k < j->iv + j->nvj; k++) {
            double r[3];
            cross(w->cols[k] + 3, x, r);  /* the column's point velocity: linear + angular x x */
            for (int d = 0; d < 3; d++) G[d * nv + k] += sign * (w->cols[k][d] + r[d]);
        }
    }
}

/* a = the constrained acceleration at (q, v) under the generalised force tau; 0 when a matrix is not
 * positive definite */
static int dynamics(const Model *m, const double *q, const double *v, const double *tau, const Push *push,
                    double *a, Work *w)
{
    const int nv = m->nv, nr = 3 * m->nc, nb = nr + 1;
    rigid_terms(m, q, v, w);
    if (!cholesky(w->M, nv, nv, w->R)) return 0;
    double pushed[MAXV];
    if (push != NULL && push->count > 0) {  /* tau + sum J_lin(x_d)^T F_d, J_lin the point's world linear rows */
        memcpy(pushed, tau, sizeof(double) * nv);
        for (int d = 0; d < push->count; d++) {
            const double *p = push->points + 4 * d, *F = push->forces + 3 * d;
            const int j = (int)p[0];
            double x[3];
            mat_vec(w->o[j].R, p + 1, x);
            for (int e = 0; e < 3; e++) x[e] += w->o[j].p[e];
            for (int s = j; s > 0; s = m->joints[s].parent)
                for (int k = m->joints[s].iv; k < m->joints[s].iv + m->joints[s].nvj; k++) {
                    double r[3];
                    cross(w->cols[k] + 3, x, r);
                    pushed[k] += F[0] * (w->cols[k][0] + r[0]) + F[1] * (w->cols[k][1] + r[1])
                                 + F[2] * (w->cols[k][2] + r[2]);
                }
        }
        tau = pushed;
    }
    /* With M = R^T R: B's columns are G^T's rows and tau - nle; Z = R^-T B by one forward substitution on all
     * columns at once (independent sums side by side); then K = Z_G^T Z_G, b = gamma - Z_G^T z_tau and, once
     * l is known, a = R^-1 (z_tau + Z_G l): M^-1 G^T is never formed. */
    double G[MAXR * MAXV], Z[MAXV * (MAXR + 1)], gamma[MAXR], K[MAXR * MAXR], KR[MAXR * MAXR];
    memset(G, 0, sizeof(double) * nr * nv);
    for (int c = 0; c < m->nc; c++) {
        const Closure *cl = &m->closures[c];
        double x1[3], x2[3], d1[3], d2[3], a1[3], a2[3];
        point_terms(m, w, cl->j1, cl->p1, 1.0, x1, d1, a1, G + 3 * c * nv);
        point_terms(m, w, cl->j2, cl->p2, -1.0, x2, d2, a2, G + 3 * c * nv);
        for (int d = 0; d < 3; d++)
            gamma[3 * c + d] = -(a1[d] - a2[d]) - cl->kp * (x1[d] - x2[d]) - cl->kd * (d1[d] - d2[d]);
    }
    const double *R = w->R;
    for (int i = 0; i < nv; i++) {  /* Z row i: (B[i] - sum_p R[p][i] Z[p]) / R[i][i], column nr = tau - nle */
        double *zi = Z + i * nb;
        for (int r = 0; r < nr; r++) zi[r] = G[r * nv + i];
        zi[nr] = tau[i] - w->nle[i];
        for (int p = 0; p < i; p++) {
            const double rpi = R[p * nv + i];
            const double *zp = Z + p * nb;
            for (int r = 0; r < nb; r++) zi[r] -= rpi * zp[r];
        }
        const double d = R[i * nv + i];
        for (int r = 0; r < nb; r++) zi[r] /= d;
    }
    double lambda[MAXR] = {0}, next[MAXR];
    if (nr > 0) {
        for (int r = 0; r < nr; r++)
            for (int s = 0; s <= r; s++) {
                double t = 0.0;
                for (int k = 0; k < nv; k++) t += Z[k * nb + r] * Z[k * nb + s];
                K[r * nr + s] = K[s * nr + r] = t + (r == s ? m->mu : 0.0);
            }
        for (int r = 0; r < nr; r++) {
            double t = 0.0;
            for (int k = 0; k < nv; k++) t += Z[k * nb + r] * Z[k * nb + nr];
            gamma[r] -= t;
        }
        if (!cholesky(K, nr, nr, KR)) return 0;
        for (int it = 0; it < m->max_iter; it++) {
            for (int r = 0; r < nr; r++) next[r] = gamma[r] + m->mu * lambda[r];
            cholesky_solve(KR, nr, next);
            double change = 0.0;
            for (int r = 0; r < nr; r++) {
                const double d = fabs(next[r] - lambda[r]);
                if (d > change) change = d;
                lambda[r] = next[r];
            }
            if (m->mu * change <= m->abs_acc || change <= m->rel_acc) break;
        }
    }
    for (int k = 0; k < nv; k++) {
        double t = Z[k * nb + nr];
        for (int r = 0; r < nr; r++) t += Z[k * nb + r] * lambda[r];
        a[k] = t;
    }
    for (int i = nv - 1; i >= 0; i--) {  /* a = R^-1 (z_tau + Z_G l) */
        double t = a[i];
        for (int p = i + 1; p < nv; p++) t -= R[i * nv + p] * a[p];
        a[i] = t / R[i * nv + i];
    }
    return 1;
}

/* ---------------------------------------------------------------- the Lie group step */
static void integrate(const Model *m, const double *q, const double *theta, double *out)
{
    for (int i = 1; i < m->nj; i++) {
        const Joint *j = &m->joints[i];
        if (j->type != FREEFLYER) {
            out[j->iq] = q[j->iq] + theta[j->iv];
            continue;
        }
        const double *t = theta + j->iv, *w = t + 3, *quat = q + j->iq + 3;
        const double n2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2], n = sqrt(n2);
        double s, b, c;  /* sin(n/2)/n, (1 - cos n)/n^2, (n - sin n)/n^3 */
        if (n < 1e-4) {
            s = 0.5 - n2 / 48.0;
            b = 0.5 - n2 / 24.0;
            c = 1.0 / 6.0 - n2 / 120.0;
        } else {
            const double h = sin(0.5 * n);
            s = h / n;
            b = 2.0 * h * h / n2;
            c = n < 0.1 ? 1.0 / 6.0 - n2 / 120.0 + n2 * n2 / 5040.0 - n2 * n2 * n2 / 362880.0
                              + n2 * n2 * n2 * n2 / 39916800.0
                        : (n - sin(n)) / (n2 * n);
        }
        double e[4] = {s * w[0], s * w[1], s * w[2], cos(0.5 * n)};
        double wv[3], wwv[3], pe[3], R[9], rp[3];
        cross(w, t, wv);
        cross(w, wv, wwv);
        for (int d = 0; d < 3; d++) pe[d] = t[d] + b * wv[d] + c * wwv[d];
        quat_matrix(quat, R);
        mat_vec(R, pe, rp);
        for (int d = 0; d < 3; d++) out[j->iq + d] = q[j->iq + d] + rp[d];
        const double x = quat[0], y = quat[1], z = quat[2], qw = quat[3];
        double r[4] = {qw * e[0] + x * e[3] + y * e[2] - z * e[1], qw * e[1] - x * e[2] + y * e[3] + z * e[0],
                       qw * e[2] + x * e[1] - y * e[0] + z * e[3], qw * e[3] - x * e[0] - y * e[1] - z * e[2]};
        if (r[0] * x + r[1] * y + r[2] * z + r[3] * qw < 0)
            for (int d = 0; d < 4; d++) r[d] = -r[d];
        const double scale = 0.5 * (3.0 - (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]));
        for (int d = 0; d < 4; d++) out[j->iq + 3 + d] = r[d] * scale;
    }
}

static const double BERNOULLI[9] = {0, 0.08333333333333333, -0.001388888888888889, 3.306878306878307e-05,
                                    -8.267195767195768e-07, 2.08767569878681e-08, -5.284190138687493e-10,
                                    1.3382536530684679e-11, -3.3896802963225827e-13}; /* B_2k / (2k)!, k <= 8 */

/* x = dexp^-1_theta(v) (the rates of theta); 0 when a free flyer turns by more than SERIES_LIMIT */
static int dexp_inverse(const Model *m, const double *theta, const double *v, double *x)
{
    for (int i = 1; i < m->nj; i++) {
        const Joint *j = &m->joints[i];
        if (j->type != FREEFLYER) {
            x[j->iv] = v[j->iv];
            continue;
        }
        const double *t = theta + j->iv;
        if (!(sqrt(t[3] * t[3] + t[4] * t[4] + t[5] * t[5]) <= SERIES_LIMIT)) return 0;
        double term[6], next[6], sum[6];
        memcpy(term, v + j->iv, sizeof term);
        memcpy(sum, term, sizeof sum);
        for (int k = 1; k <= 16; k++) {
            motion_cross(t, term, next);
            memcpy(term, next, sizeof term);
            if (k == 1) {
                for (int d = 0; d < 6; d++) sum[d] += 0.5 * term[d];
                continue;
            }
            if (k % 2) continue;
            double size = 0.0, total = 0.0;
            for (int d = 0; d < 6; d++) {
                sum[d] += BERNOULLI[k / 2] * term[d];
                size = fmax(size, fabs(BERNOULLI[k / 2] * term[d]));
                total = fmax(total, fabs(sum[d]));
            }
            if (size <= 1e-18 * total) break;
        }
        memcpy(x + j->iv, sum, sizeof sum);
    }
    return 1;
}

/* ---------------------------------------------------------------- the measured velocity */
/* v = argmin |K v - vc| (normal equations), K's rows the LOCAL Jacobians of some joints times T (rows given by
 * the spec) and constant rows elsewhere, at the model's configuration T q. spec: n, rows, nq (T's rows), T
 * (nq x n), the number of Jacobian blocks, per block (first row, joint), then the constant rows (rows x n).
 * 1 on success; 0 when K^T K is not positive definite; -1 when the spec does not fit. */
static int velocity(const Model *m, const double *spec, npy_intp spec_len, const double *q, const double *vc,
                    npy_intp vc_len, double *v)
{
    int n, rows, nqm, blocks;
    if (spec_len < 3 || !whole(spec[0], 1, MAXV, &n) || !whole(spec[1], n, 2 * MAXV, &rows)
        || !whole(spec[2], m->nq, m->nq, &nqm) || m->nq != m->nv || vc_len != rows
        || spec_len < 3 + (npy_intp)nqm * n + 1)
        return -1;
    const double *T = spec + 3;
    if (!whole(T[nqm * n], 0, rows, &blocks)
        || spec_len != 3 + (npy_intp)nqm * n + 1 + 2 * blocks + (npy_intp)rows * n)
        return -1;
    const double *block = T + nqm * n + 1, *constant = block + 2 * blocks;
    double qp[MAXV], K[2 * MAXV * MAXV], A[MAXV * MAXV], R[MAXV * MAXV];
    map_rows(T, nqm, n, q, qp);
    SE3 o[MAXJ];
    double cols[MAXV][6];
    placements(m, qp, o, NULL);  /* nq == nv: no free flyer */
    world_columns(m, o, cols);
    memcpy(K, constant, sizeof(double) * rows * n);
    for (int b = 0; b < blocks; b++) {
        int first, joint;
        if (!whole(block[2 * b], 0, rows - 6, &first) || !whole(block[2 * b + 1], 1, m->nj - 1, &joint)) return -1;
        double J[6][MAXV];
        memset(J, 0, sizeof J);
        for (int s = joint; s > 0; s = m->joints[s].parent) {
            const int k = m->joints[s].iv;
            double c[6];
            act_inv_motion(&o[joint], cols[k], c);
            for (int d = 0; d < 6; d++) J[d][k] = c[d];
        }
        for (int d = 0; d < 6; d++)
            for (int c = 0; c < n; c++) {
                double t = 0.0;
                for (int k = 0; k < nqm; k++) t += J[d][k] * T[k * n + c];
                K[(first + d) * n + c] = t;
            }
    }
    for (int a = 0; a < n; a++) {
        for (int b = 0; b <= a; b++) {
            double t = 0.0;
            for (int r = 0; r < rows; r++) t += K[r * n + a] * K[r * n + b];
            A[a * n + b] = A[b * n + a] = t;
        }
        double t = 0.0;
        for (int r = 0; r < rows; r++) t += K[r * n + a] * vc[r];
        v[a] = t;
    }
    if (!cholesky(A, n, n, R)) return 0;
    cholesky_solve(R, n, v);
    return 1;
}

/* ---------------------------------------------------------------- RKMK4 steps */
static int all_finite(const double *x, int n)
{
    double s = 0.0;
    for (int k = 0; k < n; k++) s += x[k];
    return isfinite(s);
}

static int run_steps(const Model *m, const double *force_map_t, int nw, const double *decay, const Push *push,
                     double *q, double *v, double *w, const double *w_cmd, double dt, long steps, long *done)
{
    const int nq = m->nq, nv = m->nv;
    const double half = 0.5 * dt, weights[4] = {dt / 6.0, dt / 3.0, dt / 3.0, dt / 6.0};
    double speeds[3][4 * MAXJ], forces[3][MAXV], kv[4][MAXV], kq[4][MAXV];
    double qs[2 * MAXV], vs[MAXV], theta[MAXV], qn[2 * MAXV], vn[MAXV];
    Work work;
    for (*done = 0; *done < steps; (*done)++) {
        for (int s = 0; s < 3; s++) {
            for (int r = 0; r < nw; r++) speeds[s][r] = w_cmd[r] + (w[r] - w_cmd[r]) * decay[s];
            for (int k = 0; k < nv; k++) forces[s][k] = 0.0;
            for (int r = 0; r < nw; r++) {
                const double f = speeds[s][r] * speeds[s][r];
                for (int k = 0; k < nv; k++) forces[s][k] += f * force_map_t[r * nv + k];
            }
        }
        if (!dynamics(m, q, v, forces[0], push, kv[0], &work))
            return all_finite(q, nq) && all_finite(v, nv) && all_finite(forces[0], nv) ? 2 : 1;
        memcpy(kq[0], v, sizeof(double) * nv);
        static const int force_of[4] = {0, 1, 1, 2};
        for (int stage = 1; stage < 4; stage++) {
            const double h = stage == 3 ? dt : half;
            for (int k = 0; k < nv; k++) {
                vs[k] = v[k] + h * kv[stage - 1][k];
                theta[k] = h * kq[stage - 1][k];
            }
            integrate(m, q, theta, qs);
            if (!dynamics(m, qs, vs, forces[force_of[stage]], push, kv[stage], &work))
                return all_finite(qs, nq) && all_finite(vs, nv) && all_finite(forces[force_of[stage]], nv) ? 2 : 1;
            if (!dexp_inverse(m, theta, vs, kq[stage])) return 3;
        }
        for (int k = 0; k < nv; k++) {
            theta[k] = weights[0] * kq[0][k] + weights[1] * kq[1][k] + weights[2] * kq[2][k] + weights[3] * kq[3][k];
            vn[k] = v[k] + (weights[0] * kv[0][k] + weights[1] * kv[1][k] + weights[2] * kv[2][k]
                            + weights[3] * kv[3][k]);
        }
        integrate(m, q, theta, qn);
        if (!all_finite(qn, nq) || !all_finite(vn, nv)) return 1;
        memcpy(q, qn, sizeof(double) * nq);
        memcpy(v, vn, sizeof(double) * nv);
        memcpy(w, speeds[2], sizeof(double) * nw);
    }
    return 0;
}

/* ---------------------------------------------------------------- Python */
static int model_of(PyObject *obj, Model *m)
{
    npy_intp len = 0;
    const double *k = constants_of(obj, &len);
    if (k == NULL || !parse(k, len, m)) {
        PyErr_SetString(PyExc_ValueError,
                        "the constants do not describe a model (fpr.model.multibody.model_constants)");
        return 0;
    }
    return 1;
}

/* a new contiguous float64 copy of obj with n entries (any number when n < 0), or NULL (an exception set) */
static PyArrayObject *copy_of(PyObject *obj, npy_intp n, const char *what)
{
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(obj, NPY_DOUBLE, 0, 0,
                                                        NPY_ARRAY_C_CONTIGUOUS | NPY_ARRAY_ALIGNED
                                                            | NPY_ARRAY_ENSURECOPY);
    if (a != NULL && n >= 0 && PyArray_SIZE(a) != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd values", what, (Py_ssize_t)n);
        Py_CLEAR(a);
    }
    return a;
}

#define DATA(a) ((double *)PyArray_DATA(a))

/* a contiguous float64 array of obj with n entries (a view when it already is one), or NULL (an exception set) */
static PyArrayObject *input_of(PyObject *obj, npy_intp n, const char *what)
{
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(obj, NPY_DOUBLE, 0, 0, NPY_ARRAY_IN_ARRAY);
    if (a != NULL && PyArray_SIZE(a) != n) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd values", what, (Py_ssize_t)n);
        Py_CLEAR(a);
    }
    return a;
}

static PyObject *py_steps(PyObject *self, PyObject *args)
{
    PyObject *ko, *go, *deco, *qo, *vo, *wo, *wco, *po = Py_None, *fo = Py_None;
    double w_max, dt;
    long steps;
    if (!PyArg_ParseTuple(args, "OOOOOOOddl|OO", &ko, &go, &deco, &qo, &vo, &wo, &wco, &w_max, &dt, &steps, &po,
                          &fo))
        return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    PyObject *result = NULL;
    PyArrayObject *q = NULL, *v = NULL, *w = NULL, *wc = NULL, *g = NULL, *dec = NULL, *pf = NULL;
    Push push = {0, NULL, NULL};
    if ((q = copy_of(qo, m.nq, "q")) == NULL || (v = copy_of(vo, m.nv, "v")) == NULL) goto done;
    if ((w = copy_of(wo, -1, "w")) == NULL) goto done;
    const npy_intp nw = PyArray_SIZE(w);
    if (nw > 4 * MAXJ) {
        PyErr_Format(PyExc_ValueError, "steps: at most %d rotor speeds", 4 * MAXJ);
        goto done;
    }
    if ((wc = copy_of(wco, nw, "w_command")) == NULL
        || (g = input_of(go, nw * m.nv, "force_map_t")) == NULL || (dec = input_of(deco, 3, "decay")) == NULL)
        goto done;
    /* the speeds pair up entry by entry (a transposed command would pair a rotor with another's command) and the
     * map's rows are the speeds' */
    if (!PyArray_SAMESHAPE(w, wc) || PyArray_NDIM(g) != 2 || PyArray_DIM(g, 0) != nw) {
        PyErr_SetString(PyExc_ValueError, "steps: w_command must have w's shape and force_map_t (w.size, nv)");
        goto done;
    }
    if (fo != Py_None) {  /* the points' spec (as points()) and their forces */
        npy_intp spec_len = 0;
        const double *spec = constants_of(po, &spec_len);
        if (spec == NULL || spec_len < 1 || !(spec[0] >= 0 && spec[0] <= 64) || spec_len != 1 + 4 * (npy_intp)spec[0]) {
            PyErr_SetString(PyExc_ValueError, "steps: the pushed points must be a spec as points() takes");
            goto done;
        }
        push.count = (int)spec[0], push.points = spec + 1;
        for (int d = 0; d < push.count; d++)
            if (!(push.points[4 * d] >= 0 && push.points[4 * d] < m.nj)) {
                PyErr_SetString(PyExc_ValueError, "steps: a pushed point on no joint of the model");
                goto done;
            }
        if ((pf = input_of(fo, 3 * (npy_intp)push.count, "forces")) == NULL) goto done;
        push.forces = DATA(pf);
    }
    if (!(dt > 0) || steps < 0) {
        PyErr_SetString(PyExc_ValueError, "steps: dt must be > 0 and steps >= 0");
        goto done;
    }
    double *command = DATA(wc);
    for (npy_intp r = 0; r < nw; r++) {  /* saturated to [0, w_max] as Plant.saturate (NaN stays NaN) */
        if (command[r] < 0.0) command[r] = 0.0;
        if (command[r] > w_max) command[r] = w_max;
    }
    long count = 0;
    int status;
    Py_BEGIN_ALLOW_THREADS
    status = run_steps(&m, DATA(g), (int)nw, DATA(dec), &push, DATA(q), DATA(v), DATA(w), command, dt, steps,
                       &count);
    Py_END_ALLOW_THREADS
    result = Py_BuildValue("OOOOli", q, v, w, wc, count, status);
done:
    Py_XDECREF(q), Py_XDECREF(v), Py_XDECREF(w), Py_XDECREF(wc), Py_XDECREF(g), Py_XDECREF(dec), Py_XDECREF(pf);
    return result;
}

static PyObject *py_dynamics(PyObject *self, PyObject *args)
{
    PyObject *ko, *qo, *vo, *to;
    if (!PyArg_ParseTuple(args, "OOOO", &ko, &qo, &vo, &to)) return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    PyArrayObject *q = copy_of(qo, m.nq, "q"), *v = q ? copy_of(vo, m.nv, "v") : NULL,
                  *t = v ? copy_of(to, m.nv, "tau") : NULL;
    PyObject *result = NULL;
    if (t != NULL) {
        Work work;
        if (!dynamics(&m, DATA(q), DATA(v), DATA(t), NULL, DATA(t), &work))
            PyErr_SetString(PyExc_ArithmeticError, "dynamics: a matrix is not positive definite");
        else
            result = (PyObject *)t, Py_INCREF(t);
    }
    Py_XDECREF(q), Py_XDECREF(v), Py_XDECREF(t);
    return result;
}

/* world positions of points on joints at q (spec: count, then joint, x, y, z per point) into positions, and the
 * largest distance between the two points of a closure; 0 on a spec that does not fit the model */
static int points(const Model *m, const double *q, const double *spec, npy_intp spec_len, double *positions,
                  double *closure)
{
    SE3 o[MAXJ];
    placements(m, q, o, NULL);
    const int n = (int)spec[0];
    if (spec_len != 1 + 4 * (npy_intp)n) return 0;
    for (int k = 0; k < n; k++) {
        const double *p = spec + 1 + 4 * k;
        if (!(p[0] >= 0 && p[0] < m->nj)) return 0;  /* on the double: a cast of 1e10 is undefined */
        const int j = (int)p[0];
        double t[3];
        mat_vec(o[j].R, p + 1, t);
        for (int d = 0; d < 3; d++) positions[3 * k + d] = t[d] + o[j].p[d];
    }
    double worst = 0.0;
    for (int c = 0; c < m->nc; c++) {
        const Closure *cl = &m->closures[c];
        double a[3], b[3], e = 0.0;
        mat_vec(o[cl->j1].R, cl->p1, a);
        mat_vec(o[cl->j2].R, cl->p2, b);
        for (int d = 0; d < 3; d++) {
            const double x = (a[d] + o[cl->j1].p[d]) - (b[d] + o[cl->j2].p[d]);
            e += x * x;
        }
        e = sqrt(e);
        if (e > worst || isnan(e)) worst = e;
    }
    *closure = worst;
    return 1;
}

static PyObject *py_points(PyObject *self, PyObject *args)
{
    PyObject *ko, *qo, *so;
    if (!PyArg_ParseTuple(args, "OOO", &ko, &qo, &so)) return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    npy_intp spec_len = 0;
    const double *spec = constants_of(so, &spec_len);
    if (spec == NULL || spec_len < 1 || !(spec[0] >= 0) || spec[0] > 64) {
        PyErr_SetString(PyExc_ValueError, "points: the spec must be a contiguous float64 vector (count, points)");
        return NULL;
    }
    PyArrayObject *q = copy_of(qo, m.nq, "q");
    if (q == NULL) return NULL;
    npy_intp dims[2] = {(npy_intp)spec[0], 3};
    PyArrayObject *positions = (PyArrayObject *)PyArray_SimpleNew(2, dims, NPY_DOUBLE);
    PyObject *result = NULL;
    double closure = 0.0;
    if (positions != NULL) {
        if (!points(&m, DATA(q), spec, spec_len, DATA(positions), &closure))
            PyErr_SetString(PyExc_ValueError, "points: the spec does not fit the model");
        else
            result = Py_BuildValue("Od", positions, closure);
    }
    Py_XDECREF(positions), Py_DECREF(q);
    return result;
}

static PyObject *py_velocity(PyObject *self, PyObject *args)
{
    PyObject *ko, *so, *qo, *vo;
    if (!PyArg_ParseTuple(args, "OOOO", &ko, &so, &qo, &vo)) return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    npy_intp spec_len = 0;
    const double *spec = constants_of(so, &spec_len);
    int n, rows;
    if (spec == NULL || spec_len < 4 || !whole(spec[0], 1, MAXV, &n) || !whole(spec[1], 1, 2 * MAXV, &rows)) {
        PyErr_SetString(PyExc_ValueError, "velocity: the spec must be a contiguous float64 vector (n, rows, ...)");
        return NULL;
    }
    PyArrayObject *q = input_of(qo, n, "q"), *vc = q ? input_of(vo, rows, "vc") : NULL;
    PyObject *result = NULL;
    if (vc != NULL) {
        npy_intp dims[1] = {n};
        PyArrayObject *v = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_DOUBLE);
        if (v != NULL) {
            const int status = velocity(&m, spec, spec_len, DATA(q), DATA(vc), PyArray_SIZE(vc), DATA(v));
            if (status < 0)
                PyErr_SetString(PyExc_ValueError, "velocity: the spec does not fit the model");
            else if (status == 0)
                result = Py_None, Py_INCREF(Py_None);
            else
                result = (PyObject *)v, Py_INCREF(v);
            Py_DECREF(v);
        }
    }
    Py_XDECREF(q), Py_XDECREF(vc);
    return result;
}

/* (M, nle, (J_f...)) at the model's state (T q, T v): the mass matrix, the bias forces and the LOCAL Jacobians
 * of frames (spec: n, T's rows nq, T (nq x n), the number of frames (any: one per drone of the robot,
 * fpr/model/_attitude.c taking 16), per frame its joint, rotation (9, row-major) and translation (3) in the joint's
 * frame), as Pinocchio's crba (mirrored), nonLinearEffects and getFrameJacobian(LOCAL) give them. */
static PyObject *py_frame_terms(PyObject *self, PyObject *args)
{
    PyObject *ko, *so, *qo, *vo;
    if (!PyArg_ParseTuple(args, "OOOO", &ko, &so, &qo, &vo)) return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    npy_intp spec_len = 0;
    const double *spec = constants_of(so, &spec_len);
    int n = -1, count = -1;
    if (spec != NULL && spec_len >= 3 && whole(spec[0], 1, MAXV, &n) && spec[1] == m.nq && m.nq == m.nv
        && spec_len >= 3 + (npy_intp)m.nq * n && !whole(spec[2 + m.nq * n], 0, INT_MAX, &count))
        count = -1;
    if (count < 0 || spec_len != 3 + (npy_intp)m.nq * n + 13 * (npy_intp)count) {
        PyErr_SetString(PyExc_ValueError, "frame_terms: the spec does not fit the model");
        return NULL;
    }
    const double *T = spec + 2, *frames = T + m.nq * n + 1;
    for (int f = 0; f < count; f++)
        if (!(frames[13 * f] >= 1 && frames[13 * f] < m.nj)) {
            PyErr_SetString(PyExc_ValueError, "frame_terms: a frame on no joint of the model");
            return NULL;
        }
    PyArrayObject *q = input_of(qo, n, "q"), *v = q ? input_of(vo, n, "v") : NULL;
    if (v == NULL) {
        Py_XDECREF(q);
        return NULL;
    }
    double qp[MAXV], vp[MAXV];
    map_rows(T, m.nq, n, DATA(q), qp);
    map_rows(T, m.nq, n, DATA(v), vp);
    Py_DECREF(q), Py_DECREF(v);
    Work work;
    rigid_terms(&m, qp, vp, &work);
    npy_intp dims[2] = {m.nv, m.nv}, jdims[2] = {6, m.nv};
    PyArrayObject *M = (PyArrayObject *)PyArray_SimpleNew(2, dims, NPY_DOUBLE),
                  *nle = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_DOUBLE);
    PyObject *jacobians = PyTuple_New(count), *result = NULL;
    if (M == NULL || nle == NULL || jacobians == NULL) goto done;
    memcpy(DATA(M), work.M, sizeof(double) * m.nv * m.nv);
    memcpy(DATA(nle), work.nle, sizeof(double) * m.nv);
    for (int f = 0; f < count; f++) {
        const double *fr = frames + 13 * f;
        const int joint = (int)fr[0];
        SE3 local, of;
        memcpy(local.R, fr + 1, sizeof local.R);
        memcpy(local.p, fr + 10, sizeof local.p);
        compose(&work.o[joint], &local, &of);
        PyArrayObject *J = (PyArrayObject *)PyArray_ZEROS(2, jdims, NPY_DOUBLE, 0);
        if (J == NULL) goto done;
        PyTuple_SET_ITEM(jacobians, f, (PyObject *)J);
        double *jd = DATA(J);
        for (int s = joint; s > 0; s = m.joints[s].parent) {
            const Joint *j = &m.joints[s];
            for (int k = j->iv; k < j->iv + j->nvj; k++) {
                double c[6];
                act_inv_motion(&of, work.cols[k], c);
                for (int d = 0; d < 6; d++) jd[d * m.nv + k] = c[d];
            }
        }
    }
    result = Py_BuildValue("OOO", M, nle, jacobians);
done:
    Py_XDECREF(M), Py_XDECREF(nle), Py_XDECREF(jacobians);
    return result;
}

static PyObject *py_rigid_terms(PyObject *self, PyObject *args)
{
    PyObject *ko, *qo, *vo;
    if (!PyArg_ParseTuple(args, "OOO", &ko, &qo, &vo)) return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    PyArrayObject *q = copy_of(qo, m.nq, "q"), *v = q ? copy_of(vo, m.nv, "v") : NULL;
    PyObject *result = NULL;
    if (v != NULL) {
        Work work;
        rigid_terms(&m, DATA(q), DATA(v), &work);
        npy_intp dims[2] = {m.nv, m.nv};
        PyArrayObject *M = (PyArrayObject *)PyArray_SimpleNew(2, dims, NPY_DOUBLE),
                      *nle = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_DOUBLE);
        if (M != NULL && nle != NULL) {
            memcpy(DATA(M), work.M, sizeof(double) * m.nv * m.nv);
            memcpy(DATA(nle), work.nle, sizeof(double) * m.nv);
            result = Py_BuildValue("OO", M, nle);
        }
        Py_XDECREF(M), Py_XDECREF(nle);
    }
    Py_XDECREF(q), Py_XDECREF(v);
    return result;
}

static PyObject *py_integrate(PyObject *self, PyObject *args)
{
    PyObject *ko, *qo, *to;
    if (!PyArg_ParseTuple(args, "OOO", &ko, &qo, &to)) return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    PyArrayObject *q = copy_of(qo, m.nq, "q"), *t = q ? copy_of(to, m.nv, "theta") : NULL,
                  *out = t ? copy_of(qo, m.nq, "q") : NULL;
    if (out != NULL) integrate(&m, DATA(q), DATA(t), DATA(out));
    Py_XDECREF(q), Py_XDECREF(t);
    return (PyObject *)out;
}

static PyObject *py_dexp_inverse(PyObject *self, PyObject *args)
{
    PyObject *ko, *to, *vo;
    if (!PyArg_ParseTuple(args, "OOO", &ko, &to, &vo)) return NULL;
    Model m;
    if (!model_of(ko, &m)) return NULL;
    PyArrayObject *t = copy_of(to, m.nv, "theta"), *v = t ? copy_of(vo, m.nv, "v") : NULL,
                  *out = v ? copy_of(vo, m.nv, "v") : NULL;
    PyObject *result = (PyObject *)out;
    if (out != NULL && !dexp_inverse(&m, DATA(t), DATA(v), DATA(out))) {
        Py_DECREF(out);
        result = Py_None, Py_INCREF(Py_None);
    }
    Py_XDECREF(t), Py_XDECREF(v);
    return result;
}

static PyMethodDef methods[] = {
    {"steps", py_steps, METH_VARARGS, "RKMK4 steps of the plant (see the module's C source)."},
    {"dynamics", py_dynamics, METH_VARARGS, "Constrained acceleration at (q, v) under tau."},
    {"frame_terms", py_frame_terms, METH_VARARGS, "(M, nle, frame Jacobians) at (T q, T v) (see the C source)."},
    {"velocity", py_velocity, METH_VARARGS, "Least-squares v of K(q) v = vc, or None (see the C source)."},
    {"points", py_points, METH_VARARGS, "(positions, closure error) of points on joints at q."},
    {"rigid_terms", py_rigid_terms, METH_VARARGS, "(M, nle) at (q, v): the mass matrix and the bias forces."},
    {"integrate", py_integrate, METH_VARARGS, "q (+) theta on the configuration group."},
    {"dexp_inverse", py_dexp_inverse, METH_VARARGS, "dexp^-1_theta(v), or None beyond the series' range."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "fpr.model._multibody",
                                    "The plant's RKMK4 steps in C (fpr.sim.plant).", -1, methods};

PyMODINIT_FUNC PyInit__multibody(void)
{
    import_array();
    return PyModule_Create(&module);
}
