/*
 * ThermalNetwork -- lumped RC network of the bearing tester's bodies (equations in readme.md).
 *
 *   C_i dT_i/dt = sum_j G_ij (T_j - T_i) + G_i,room (T_room - T_i) + s^hyd_i Q_hyd + s^fric_i Q_fric
 *                 (+ Q_heater into the lower pole)
 *
 * Written as dT/dt = A T + B u with u = (T_room, Q_hyd, Q_fric, Q_heater) held constant over each internal
 * step (zero-order hold, exactly what a co-simulation master delivers). The step map is exact:
 * [phi gamma; psi lambda] come from one matrix exponential of the augmented system
 *
 *   d/dt [T; S; u] = [A 0 B; I 0 0; 0 0 0] [T; S; u],   S = integral of T over the step,
 *
 * computed once at initialization. Exact for any step, so unconditionally stable; the integral
 * S gives the heat lost to the room exactly, which the energy-balance outputs use.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "linalg.h"
#include "model.h"

/* node order used by every table below */
static const int VR_T[TN_NODES] = {VR_t_base, VR_t_heel_block, VR_t_bearing_block, VR_t_spindle, VR_t_bearing,
                                   VR_t_t_plate, VR_t_detecting_frame, VR_t_pole_heel, VR_t_pole_base, VR_t_pole_lower,
                                   VR_t_clamp, VR_t_sensor, VR_t_oil, VR_t_detecting_frame_lower,
                                   VR_t_drive_train, VR_t_bearing_block_rear, VR_t_floor,
                                   VR_t_bearing_block_cap};
static const int VR_C[TN_NODES] = {VR_c_base, VR_c_heel_block, VR_c_bearing_block, VR_c_spindle, VR_c_bearing,
                                   VR_c_t_plate, VR_c_detecting_frame, VR_c_pole_heel, VR_c_pole_base, VR_c_pole_lower,
                                   VR_c_clamp, VR_c_sensor, VR_c_oil, VR_c_detecting_frame_lower,
                                   VR_c_drive_train, VR_c_bearing_block_rear, VR_c_floor,
                                   VR_c_bearing_block_cap};
static const int VR_GROOM[TN_NODES] = {VR_g_base_room, VR_g_heel_block_room, VR_g_bearing_block_room, VR_g_spindle_room,
                                       VR_g_bearing_room, VR_g_t_plate_room, VR_g_detecting_frame_room,
                                       VR_g_pole_heel_room, VR_g_pole_base_room, VR_g_pole_lower_room, VR_g_clamp_room,
                                       VR_g_sensor_room, VR_g_oil_room, VR_g_detecting_frame_lower_room,
                                       VR_g_drive_train_room, VR_g_bearing_block_rear_room,
                                       VR_g_floor_room, VR_g_bearing_block_cap_room};
static const int VR_HYD[TN_NODES] = {VR_hyd_share_base, VR_hyd_share_heel_block, VR_hyd_share_bearing_block,
                                     VR_hyd_share_spindle, VR_hyd_share_bearing, VR_hyd_share_t_plate,
                                     VR_hyd_share_detecting_frame, VR_hyd_share_pole_heel, VR_hyd_share_pole_base,
                                     VR_hyd_share_pole_lower, VR_hyd_share_clamp, VR_hyd_share_sensor, VR_hyd_share_oil,
                                     VR_hyd_share_detecting_frame_lower, VR_hyd_share_drive_train,
                                     VR_hyd_share_bearing_block_rear, VR_hyd_share_floor,
                                     VR_hyd_share_bearing_block_cap};
static const int VR_FRIC[TN_NODES] = {VR_fric_share_base, VR_fric_share_heel_block, VR_fric_share_bearing_block,
                                      VR_fric_share_spindle, VR_fric_share_bearing, VR_fric_share_t_plate,
                                      VR_fric_share_detecting_frame, VR_fric_share_pole_heel, VR_fric_share_pole_base,
                                      VR_fric_share_pole_lower, VR_fric_share_clamp, VR_fric_share_sensor,
                                      VR_fric_share_oil, VR_fric_share_detecting_frame_lower,
                                      VR_fric_share_drive_train, VR_fric_share_bearing_block_rear,
                                      VR_fric_share_floor, VR_fric_share_bearing_block_cap};
static const int VR_TSTART[TN_NODES] = {VR_t_start_base, VR_t_start_heel_block, VR_t_start_bearing_block,
                                        VR_t_start_spindle, VR_t_start_bearing, VR_t_start_t_plate,
                                        VR_t_start_detecting_frame, VR_t_start_pole_heel, VR_t_start_pole_base,
                                        VR_t_start_pole_lower, VR_t_start_clamp, VR_t_start_sensor, VR_t_start_oil,
                                        VR_t_start_detecting_frame_lower, VR_t_start_drive_train,
                                        VR_t_start_bearing_block_rear, VR_t_start_floor,
                                        VR_t_start_bearing_block_cap};

/* the detecting frame is two lumps along its length: FRAME (upper half, fixed in the base) and
 * FRAME_LOWER (lower half, carrying the sensor); appended last so the older nodes keep their order.
 * DRIVE is the transmission module behind the spindle (motor, reducer, coupling: its own mass
 * behind the coupling, not an inflated spindle); BBLOCK_REAR is the bearing block's rear half
 * (toward the drive), BBLOCK then its front half (toward the T-plate, holding the roller bearing):
 * two nodes across the block, so a gradient along the spindle can exist and tilt the block.
 * FLOOR is the concrete slab the transmission stands on: the slowest mass of the tester's
 * surroundings, a day's warming reaches only its top decimetre. BBLOCK_CAP is the block's upper
 * part above the spindle's axis, joined to the two lower halves only beside the bore: the block's
 * thermometer sits on it (its top face), nearer the room air than the foot on the heel block. */
enum {
    BASE,
    HEEL,
    BBLOCK,
    SPINDLE,
    BEARING,
    TPLATE,
    FRAME,
    POLE_HEEL,
    POLE_BASE,
    POLE_LOWER,
    CLAMP,
    SENSOR,
    OIL,
    FRAME_LOWER,
    DRIVE,
    BBLOCK_REAR,
    FLOOR,
    BBLOCK_CAP
};

/* the network's edges: which bodies touch, and the parameter holding the conductance */
static const struct { int a, b, vr; } EDGES[TN_EDGES] = {
    {BASE, HEEL, VR_g_base__heel_block},
    {HEEL, BBLOCK, VR_g_heel_block__bearing_block},
    {BBLOCK, SPINDLE, VR_g_bearing_block__spindle},
    {SPINDLE, BEARING, VR_g_spindle__bearing},
    {BEARING, TPLATE, VR_g_bearing__t_plate},
    {BASE, FRAME, VR_g_base__detecting_frame},
    {HEEL, POLE_HEEL, VR_g_heel_block__pole_heel},
    {BASE, POLE_BASE, VR_g_base__pole_base},
    {FRAME_LOWER, POLE_LOWER, VR_g_detecting_frame_lower__pole_lower},
    {POLE_HEEL, POLE_BASE, VR_g_pole_heel__pole_base},
    {POLE_BASE, POLE_LOWER, VR_g_pole_base__pole_lower},
    {POLE_LOWER, CLAMP, VR_g_pole_lower__clamp},
    {CLAMP, SENSOR, VR_g_clamp__sensor},
    {SENSOR, FRAME_LOWER, VR_g_sensor__detecting_frame_lower},
    {FRAME, FRAME_LOWER, VR_g_detecting_frame__detecting_frame_lower},
    {TPLATE, POLE_HEEL, VR_g_t_plate__pole_heel},
    {OIL, BASE, VR_g_oil__base},
    {SPINDLE, DRIVE, VR_g_spindle__drive_train},
    {HEEL, BBLOCK_REAR, VR_g_heel_block__bearing_block_rear},
    {BBLOCK, BBLOCK_REAR, VR_g_bearing_block__bearing_block_rear},
    {DRIVE, FLOOR, VR_g_drive_train__floor},
    {BBLOCK, BBLOCK_CAP, VR_g_bearing_block__bearing_block_cap},
    {BBLOCK_REAR, BBLOCK_CAP, VR_g_bearing_block_rear__bearing_block_cap},
};

static double share_sum(const ModelInstance *comp, const int *vrs) {
    double s = 0.0;
    int i;
    for (i = 0; i < TN_NODES; i++) s += comp->v.r[vrs[i]];
    return s;
}

static void augmented(const ModelInstance *comp, double h, double *aug);

/* The most squarings the step map may take: each doubles its rounding (2^s eps). Measured on
 * a network made stiff through its sensor node (tests/fmus/test_thermal_network.py), 60 days at
 * constant heat: 24 squarings leave the steady state 5e-8 K from the analytic one and the energy
 * balance within 2e-9 of the heat put in; 28 leave 5e-7 K, 38 leave 5e-4 K. The nominal network
 * takes 13 at the longest solver_step (3600 s). */
#define TN_MAX_SQUARINGS 24

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    double sh = share_sum(comp, VR_HYD), sf = share_sum(comp, VR_FRIC);
    double aug[TN_AUG * TN_AUG], h = comp->v.r[VR_solver_step];
    int squarings;
    /* shares that do not add up to one would create or destroy energy */
    if (fabs(sh - 1.0) > 1e-9) {
        snprintf(msg, msg_size, "the hyd_share_* parameters sum to %.12g, they must sum to 1", sh);
        return -1;
    }
    if (fabs(sf - 1.0) > 1e-9) {
        snprintf(msg, msg_size, "the fric_share_* parameters sum to %.12g, they must sum to 1", sf);
        return -1;
    }
    augmented(comp, h, aug);
    squarings = la_expm_squarings(TN_AUG, aug);
    if (squarings < 0) {
        snprintf(msg, msg_size, "the network's matrix is not finite: check capacities and conductances");
        return -1;
    }
    if (squarings > TN_MAX_SQUARINGS) {
        /* the norm halves with the step: this step takes the squarings to the limit */
        double h_max = ldexp(h, TN_MAX_SQUARINGS - squarings);
        snprintf(msg, msg_size,
                 "the network is too stiff for solver_step = %g s: a node's capacity is small for its conductances, "
                 "and the step map would take %d squarings, each doubling its rounding (at most %d keep it "
                 "accurate); take solver_step <= %.3g s, or larger capacities or smaller conductances",
                 h, squarings, TN_MAX_SQUARINGS, h_max);
        return -1;
    }
    return 0;
}

static void inputs(const ModelInstance *comp, double u[TN_INPUTS]) {
    u[0] = comp->v.r[VR_t_room];
    u[1] = comp->v.r[VR_q_hydraulic];
    u[2] = comp->v.r[VR_q_friction];
    u[3] = comp->v.r[VR_q_pole_heater];
}

/* What the exact step map is, whatever the parameters: its weights are never negative (the
 * exponential of a matrix with non-negative off-diagonals), and a network at room temperature
 * without heat input stays there: each row of phi plus its room column of gamma sums to one, each
 * row of psi plus its room column of lambda to h. The squarings of la_expm multiply rounding by
 * 2^s, and a stiff network at a long solver_step takes s up to about 40 (a 1 mJ/K node on a
 * 100 kW/K conductance at 3600 s): then a network at room temperature drifted by 0.1 K in 20 h
 * and cooled below the coldest temperature it was given. Restoring both properties keeps every
 * new temperature a weighted mean of the node and room temperatures plus the heat put in; at the
 * nominal parameters (s = 2 to 14) it changes the room columns in their last bits. */
static void keep_structure(ModelState *m, double h) {
    int i, j;
    for (i = 0; i < TN_NODES; i++) {
        double *phi = &m->phi[i * TN_NODES], *psi = &m->psi[i * TN_NODES];
        double *gamma = &m->gamma[i * TN_INPUTS], *lambda = &m->lambda[i * TN_INPUTS];
        double sum_phi = 0.0, sum_psi = 0.0;
        for (j = 0; j < TN_NODES; j++) {
            phi[j] = fmax(phi[j], 0.0);
            psi[j] = fmax(psi[j], 0.0);
        }
        for (j = 0; j < TN_INPUTS; j++) {
            gamma[j] = fmax(gamma[j], 0.0);
            lambda[j] = fmax(lambda[j], 0.0);
        }
        for (j = 0; j < TN_NODES; j++) sum_phi += phi[j];
        if (sum_phi > 1.0) { /* then the room column is below the rounding: it is zero */
            for (j = 0; j < TN_NODES; j++) phi[j] /= sum_phi;
            sum_phi = 1.0;
        }
        for (j = 0; j < TN_NODES; j++) sum_psi += psi[j];
        if (sum_psi > h) {
            for (j = 0; j < TN_NODES; j++) psi[j] *= h / sum_psi;
            sum_psi = h;
        }
        gamma[0] = fmax(1.0 - sum_phi, 0.0); /* column 0 of the inputs is t_room */
        lambda[0] = fmax(h - sum_psi, 0.0);
    }
}

/* The augmented system's matrix times h (see the top of this file). */
static void augmented(const ModelInstance *comp, double h, double *aug) {
    static const size_t N = TN_AUG;
    int i, k;
    memset(aug, 0, N * N * sizeof *aug);
    for (k = 0; k < TN_EDGES; k++) {
        int a = EDGES[k].a, b = EDGES[k].b;
        double g = comp->v.r[EDGES[k].vr];
        aug[a * N + a] -= g / comp->v.r[VR_C[a]];
        aug[a * N + b] += g / comp->v.r[VR_C[a]];
        aug[b * N + b] -= g / comp->v.r[VR_C[b]];
        aug[b * N + a] += g / comp->v.r[VR_C[b]];
    }
    for (i = 0; i < TN_NODES; i++) {
        double c = comp->v.r[VR_C[i]];
        double groom = comp->v.r[VR_GROOM[i]];
        aug[i * N + i] -= groom / c;
        aug[i * N + 2 * TN_NODES + 0] = groom / c;
        aug[i * N + 2 * TN_NODES + 1] = comp->v.r[VR_HYD[i]] / c;
        aug[i * N + 2 * TN_NODES + 2] = comp->v.r[VR_FRIC[i]] / c;
        aug[i * N + 2 * TN_NODES + 3] = i == POLE_LOWER ? 1.0 / c : 0.0; /* the heater tape */
        aug[(TN_NODES + i) * N + i] = 1.0;                             /* S' = T */
    }
    for (i = 0; i < (int)(N * N); i++) aug[i] *= h;
}

/* out = x y + add (+ add2), an n x n times n x c product of row-major blocks, each sum over the
 * n products in order, then the blocks added (add, add2 may be NULL). */
static void block_product(int n, int c, const double *x, const double *y, const double *add, const double *add2,
                          double *out) {
    int i, j, k;
    for (i = 0; i < n; i++) {
        for (j = 0; j < c; j++) {
            double s = 0.0;
            for (k = 0; k < n; k++) s += x[i * n + k] * y[k * c + j];
            if (add) s += add[i * c + j];
            if (add2) s += add2[i * c + j];
            out[i * c + j] = s;
        }
    }
}

/* The exponential of the augmented matrix aug = [A 0 B; I 0 0; 0 0 0] h in its four blocks
 * [phi . gamma; psi . lambda]: the doubles la_expm(TN_AUG, aug, ...) gives there, bit for bit,
 * at a fifth of its work (it is most of an instance's set-up, once per Monte Carlo sample).
 *
 * la_expm scales aug, sums the Taylor terms term_k = term_(k-1) aug / k and squares the sum.
 * Every term (k >= 1) and every partial sum keeps aug's zero blocks, so each of their products
 * is a sum of the same nonzero products in the same order as the full product's, whose other
 * products are zeros, which leave a sum unchanged: a term's blocks are [T . U; W . V] with
 * T' = T a, U' = T b, W' = W a, V' = W b (a, b the scaled A h, B h; the first term is the scaled
 * matrix itself, W = I h); a square of [E . G; P I L] is E' = E E, G' = E G + G,
 * P' = P E + P, L' = (P G + L) + L, its identity blocks staying the identity. */
static int expm_blocks(const double *aug, ModelState *m) {
    enum { n = TN_NODES, q = TN_INPUTS, N = TN_AUG };
    double a[n * n], b[n * q], t[n * n], u[n * q], w[n * n], v[n * q];
    double t2[n * n], u2[n * q], w2[n * n], v2[n * q];
    double *e = m->phi, *g = m->gamma, *p = m->psi, *l = m->lambda;
    double scale;
    int squarings = la_expm_squarings(N, aug), i, j, k;
    if (squarings < 0) return -1;
    scale = ldexp(1.0, -squarings);
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) a[i * n + j] = aug[i * N + j] * scale;
        for (j = 0; j < q; j++) b[i * q + j] = aug[i * N + 2 * n + j] * scale;
    }
    /* the first term (k = 1): the scaled matrix, added to the identity */
    memcpy(t, a, sizeof t);
    memcpy(u, b, sizeof u);
    memset(w, 0, sizeof w);
    memset(v, 0, sizeof v);
    for (i = 0; i < n; i++) w[i * n + i] = aug[(n + i) * N + i] * scale;
    for (i = 0; i < n * n; i++) e[i] = (i % (n + 1) == 0 ? 1.0 : 0.0) + t[i];
    for (i = 0; i < n * q; i++) g[i] = 0.0 + u[i];
    for (i = 0; i < n * n; i++) p[i] = 0.0 + w[i];
    for (i = 0; i < n * q; i++) l[i] = 0.0 + v[i];
    for (k = 2; k <= 20; k++) {
        block_product(n, n, t, a, NULL, NULL, t2);
        block_product(n, q, t, b, NULL, NULL, u2);
        block_product(n, n, w, a, NULL, NULL, w2);
        block_product(n, q, w, b, NULL, NULL, v2);
        for (i = 0; i < n * n; i++) {
            t[i] = t2[i] / (double)k;
            w[i] = w2[i] / (double)k;
            e[i] += t[i];
            p[i] += w[i];
        }
        for (i = 0; i < n * q; i++) {
            u[i] = u2[i] / (double)k;
            v[i] = v2[i] / (double)k;
            g[i] += u[i];
            l[i] += v[i];
        }
    }
    for (k = 0; k < squarings; k++) {
        block_product(n, n, e, e, NULL, NULL, t2);
        block_product(n, q, e, g, g, NULL, u2);
        block_product(n, n, p, e, p, NULL, w2);
        block_product(n, q, p, g, l, l, v2);
        memcpy(e, t2, sizeof t2);
        memcpy(g, u2, sizeof u2);
        memcpy(p, w2, sizeof w2);
        memcpy(l, v2, sizeof v2);
    }
    return 0;
}

/* Builds the step matrices for step h from the parameters. */
static fmi2Status make_step_matrices(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    double aug[TN_AUG * TN_AUG];

    augmented(comp, h, aug);
    if (expm_blocks(aug, m) != 0) {
        log_error(comp, "thermal network matrix is not finite: check capacities and conductances");
        return fmi2Error;
    }
    keep_structure(m, h);
    m->phi_h = h;
    return fmi2OK;
}

static double heat_content(const ModelInstance *comp) {
    double s = 0.0;
    int i;
    for (i = 0; i < TN_NODES; i++) s += comp->v.r[VR_C[i]] * comp->v.m.temp[i];
    return s;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    int i;
    for (i = 0; i < TN_NODES; i++)
        m->temp[i] = comp->v.b[VR_start_at_room] ? comp->v.r[VR_t_room] : comp->v.r[VR_TSTART[i]];
    m->energy_stored0 = heat_content(comp);
    m->energy_in = 0.0;
    m->energy_lost = 0.0;
    return make_step_matrices(comp, comp->v.r[VR_solver_step]);
}

fmi2Status model_step(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    double u[TN_INPUTS], tnew[TN_NODES], tint[TN_NODES], gu[TN_NODES], lu[TN_NODES], lost = 0.0;
    int i;
    inputs(comp, u);
    la_matvec(TN_NODES, TN_NODES, m->phi, m->temp, tnew);
    la_matvec(TN_NODES, TN_INPUTS, m->gamma, u, gu);
    la_matvec(TN_NODES, TN_NODES, m->psi, m->temp, tint);
    la_matvec(TN_NODES, TN_INPUTS, m->lambda, u, lu);
    for (i = 0; i < TN_NODES; i++) {
        tnew[i] += gu[i];
        tint[i] += lu[i];
        lost += comp->v.r[VR_GROOM[i]] * (tint[i] - h * u[0]);
    }
    memcpy(m->temp, tnew, sizeof tnew);
    m->energy_in += h * (u[1] * share_sum(comp, VR_HYD) + u[2] * share_sum(comp, VR_FRIC) + u[3]);
    m->energy_lost += lost;
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    int i;
    for (i = 0; i < TN_NODES; i++) comp->v.r[VR_T[i]] = m->temp[i];
    comp->v.r[VR_t_ambient] = comp->v.r[VR_t_room];
    comp->v.r[VR_energy_stored] = heat_content(comp) - m->energy_stored0;
    comp->v.r[VR_energy_in] = m->energy_in;
    comp->v.r[VR_energy_lost] = m->energy_lost;
}

/* A state handed back: the step matrices those of the parameters, the energies finite (the heat
 * put in between 0 and the most the inputs can bring), every temperature finite and not below
 * the coldest start or room temperature the ranges allow (with heat inputs >= 0 and the exact,
 * positive step map no node ever cools below that). */
int model_check_state(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    double elapsed = (double)comp->v.steps_taken * r[VR_solver_step];
    double q_max = real_var(VR_q_hydraulic)->max + real_var(VR_q_friction)->max + real_var(VR_q_pole_heater)->max;
    double t_low = real_var(VR_t_room)->min;
    ModelInstance fresh = *comp;
    int i;
    for (i = 0; i < TN_NODES; i++)
        if (real_var(VR_TSTART[i])->min < t_low) t_low = real_var(VR_TSTART[i])->min;
    if (state_bad_reals(c, "node temperature", m->temp, TN_NODES, t_low - 1e-6, HUGE_VAL) ||
        state_bad_real(c, "energy_stored0", m->energy_stored0, -HUGE_VAL, HUGE_VAL) ||
        state_bad_real(c, "energy_in", m->energy_in, 0.0, q_max * elapsed * (1.0 + 1e-6)) ||
        state_bad_real(c, "energy_lost", m->energy_lost, -HUGE_VAL, HUGE_VAL))
        return -1;
    if (m->phi_h != r[VR_solver_step]) {
        state_fail(c, "step matrices made for %.17g s, not for solver_step = %.17g s", m->phi_h, r[VR_solver_step]);
        return -1;
    }
    if (make_step_matrices(&fresh, m->phi_h) != fmi2OK) {
        state_fail(c, "the step matrices cannot be computed from the parameters");
        return -1;
    }
    if (state_bad_match(c, "phi", m->phi, fresh.v.m.phi, TN_NODES * TN_NODES) ||
        state_bad_match(c, "gamma", m->gamma, fresh.v.m.gamma, TN_NODES * TN_INPUTS) ||
        state_bad_match(c, "psi", m->psi, fresh.v.m.psi, TN_NODES * TN_NODES) ||
        state_bad_match(c, "lambda", m->lambda, fresh.v.m.lambda, TN_NODES * TN_INPUTS))
        return -1;
    return 0;
}
