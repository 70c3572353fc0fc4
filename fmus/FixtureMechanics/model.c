/*
 * FixtureMechanics -- the two branches of the wear-depth detecting system along Z
 * (equations in readme.md). Z is the wear direction, positive DOWN.
 *
 * Branch 1 (bearing side): base -> heel block + bearing block -> spindle -> bearing -> T-plate.
 * Branch 2 (detecting side): base (its inset) -> detecting frame -> probe body -> clamp -> long pole.
 * The loop closes: from the base top, branch 1 rises by the heel and bearing blocks and comes
 * down by spindle radius, rings and T-plate to the T-plate's bottom (-0.140 m as drawn), the pole
 * and clamp come down 0.512 m to the contact face (0.372 m); branch 2 comes down by the base's
 * inset and the frame (0.050 + 0.362 m) and back up by the probe's body (0.040 m) to the same
 * 0.372 m. So a uniform rise with one expansion coefficient moves the reading by alpha dT times
 * the probe's own few-millimetre reading only (tests/fmus/test_mechanics_loop.py).
 * The spring keeps the long pole's top on the T-plate's bottom; the clamp on the pole
 * presses the probe's head; the probe reads the clamp's Z position relative to the sensor.
 * All displacements are small (micrometres), so each body's thermal term is linear:
 * alpha * L * (T - T_ref). The liner's wear is the one state: an Archard-type rate
 * dh/ds = k(s) p with a running-in phase k(s) = k (1 + f exp(-s/s0)), integrated exactly in
 * the sliding distance s over each internal step (inputs held over the step).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"

#define G_ACCEL 9.80665 /* m/s2, standard gravity */

static const int VR_TEMPS[FM_TEMPS] = {VR_t_heel_block, VR_t_bearing_block, VR_t_spindle, VR_t_bearing,
                                       VR_t_t_plate, VR_t_detecting_frame, VR_t_pole_heel, VR_t_pole_base,
                                       VR_t_pole_lower, VR_t_clamp, VR_t_detecting_frame_lower, VR_t_base,
                                       VR_t_sensor, VR_t_bearing_block_rear};
/* BBLOCK is the bearing block's lower front half (toward the T-plate), BBLOCK_REAR its lower rear
 * half (toward the drive): appended last so the older inputs keep their order */
enum { HEEL, BBLOCK, SPINDLE, BEARING, TPLATE, FRAME, POLE_HEEL, POLE_BASE, POLE_LOWER, CLAMP, FRAME_LOWER, BASE,
       SENSOR, BBLOCK_REAR };

/* The parts that grow: each has its own expansion coefficient (parts of one material still
 * differ, so a tester as built draws them apart, and the pole's and the frame's do not cancel)
 * and its own factor from its lump's rise to its mean rise (a thermometer reads a point). */
enum { P_HEEL, P_BBLOCK, P_SPINDLE, P_RINGS, P_TPLATE, P_FRAME, P_POLE, P_CLAMP, P_BASE, P_PROBE, FM_PARTS };
static const int VR_ALPHAS[FM_PARTS] = {VR_alpha_heel_block, VR_alpha_bearing_block, VR_alpha_spindle,
                                        VR_alpha_bearing_rings, VR_alpha_t_plate, VR_alpha_detecting_frame,
                                        VR_alpha_long_pole, VR_alpha_clamp, VR_alpha_base, VR_alpha_probe_body};
static const int VR_RISES[FM_PARTS] = {VR_rise_factor_heel_block, VR_rise_factor_bearing_block,
                                       VR_rise_factor_spindle, VR_rise_factor_bearing_rings,
                                       VR_rise_factor_t_plate, VR_rise_factor_detecting_frame,
                                       VR_rise_factor_long_pole, VR_rise_factor_clamp, VR_rise_factor_base,
                                       VR_rise_factor_probe_body};

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    double *r = comp->v.r;
    if (r[VR_k_spring] + r[VR_k_head] <= 0.0) {
        snprintf(msg, msg_size, "k_spring + k_head must be > 0 (the pole needs a restoring force)");
        return -1;
    }
    return 0;
}

/* The liner's elastic compression under the load: thickness x pressure / E, with the modulus
 * falling as the bearing warms above its start, E = E0 (1 - c dT) (not below a tenth of E0). */
static double liner_elastic(const ModelInstance *comp) {
    const double *r = comp->v.r;
    double soften = 1.0 - r[VR_liner_modulus_tempco] * (r[VR_t_bearing] - comp->v.m.t_ref[BEARING]);
    if (soften < 0.1) soften = 0.1;
    return r[VR_liner_thickness] / (r[VR_liner_modulus] * soften * r[VR_contact_area]) * r[VR_radial_load];
}

/* Hysteresis of the liner: a play operator of width w on its elastic compression. The output
 * stays where it was until the compression moves more than w/2 away from it. */
static double liner_play(const ModelInstance *comp, double elastic) {
    double half = 0.5 * comp->v.r[VR_liner_hysteresis], y = comp->v.m.liner_play;
    if (y < elastic - half) y = elastic - half;
    if (y > elastic + half) y = elastic + half;
    return y;
}

fmi2Status model_initialize(ModelInstance *comp) {
    int i;
    for (i = 0; i < FM_TEMPS; i++)
        comp->v.m.t_ref[i] = comp->v.b[VR_reference_at_start] ? comp->v.r[VR_TEMPS[i]] : comp->v.r[VR_t_reference];
    comp->v.m.wear = 0.0;
    comp->v.m.sliding_distance = 0.0;
    comp->v.m.creep = 0.0; /* the probe is zeroed with the load on: creep starts then */
    comp->v.m.liner_play = liner_elastic(comp);
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    const double *r = comp->v.r;
    ModelState *m = &comp->v.m;
    Memo *memo = comp->memo;
    double ds = r[VR_sliding_speed] * h, s0 = r[VR_running_in_distance];
    /* exact integral of k(s) p ds over [s, s + ds] */
    double running_in = r[VR_running_in_factor] * s0 *
                        (memo_call(&memo[MEMO_RUNNING_IN], exp, -m->sliding_distance / s0) -
                         memo_call(&memo[MEMO_RUNNING_IN], exp, -(m->sliding_distance + ds) / s0));
    double elastic = liner_elastic(comp);
    m->wear += r[VR_wear_rate] * r[VR_contact_pressure] * (ds + running_in);
    m->sliding_distance += ds;
    /* creep: first-order approach to ratio x elastic compression, exact for the held load */
    m->creep += (r[VR_liner_creep_ratio] * elastic - m->creep) * -memo_call(&memo[MEMO_CREEP_GAIN], expm1, -h / r[VR_liner_creep_time]);
    m->liner_play = liner_play(comp, elastic);
    return fmi2OK;
}

/* Each output is written into its slot of r where it is computed, and later equations read
 * it back from there: the outputs are the model's variables, with no second copy of them. */

/* The paper's characteristic matrices are 4x4 homogeneous transforms (row-major here). A body's
 * small rotation A about X (the paper's A axis) about a pivot p: T = Trans(p) Rot_x(A) Trans(-p). */
static void rotation_about_x(Memo *memo, double a, const double pivot[3], double t[16]) {
    double c = memo_call(&memo[MEMO_TILT_COS], cos, a), s = memo_call(&memo[MEMO_TILT_SIN], sin, a);
    double rot[16] = {1, 0, 0, 0, 0, c, -s, 0, 0, s, c, 0, 0, 0, 0, 1};
    int i;
    memcpy(t, rot, sizeof rot);
    /* translation column: p - R p */
    for (i = 0; i < 3; i++) t[i * 4 + 3] = pivot[i] - (rot[i * 4] * pivot[0] + rot[i * 4 + 1] * pivot[1] + rot[i * 4 + 2] * pivot[2]);
}

static void transform_point(const double t[16], const double p[3], double out[3]) {
    int i;
    for (i = 0; i < 3; i++) out[i] = t[i * 4] * p[0] + t[i * 4 + 1] * p[1] + t[i * 4 + 2] * p[2] + t[i * 4 + 3];
}

/* The bearing block's tilt: its front half (toward the T-plate, +Y) warmer than its rear half
 * grows taller by alpha h dT over the halves' distance d, so the block and the spindle it holds
 * turn about X by A = alpha h (dT_front - dT_rear) / d, the front going up (-Z): A = -that in the
 * right-handed frame (Y toward the T-plate, Z down). The pivot is the block's foot centre; the
 * test bearing sits at the overhang along +Y, on the spindle's axis h above the foot. Its Z
 * through the block's homogeneous matrix, less where it was, is the tilt's part of z_t_plate. */
static void bearing_block_tilt(Memo *memo, double *r, const double *dt, double alpha_block) {
    double h = r[VR_h_bearing_block], foot[3] = {0.0, 0.0, 0.0}, bearing[3], moved[3], t[16];
    r[VR_bearing_block_gradient] = dt[BBLOCK] - dt[BBLOCK_REAR];
    r[VR_bearing_block_tilt] = -alpha_block * h * r[VR_bearing_block_gradient] / r[VR_d_bearing_block_halves];
    bearing[0] = 0.0;
    bearing[1] = r[VR_l_overhang];
    bearing[2] = -h;
    rotation_about_x(memo, r[VR_bearing_block_tilt], foot, t);
    transform_point(t, bearing, moved);
    r[VR_dz_bearing_block_tilt] = moved[2] - bearing[2];
}

/* Branch 1: heel and bearing block grow up (-Z); below the spindle axis the spindle radius,
 * the bearing rings and the T-plate grow down (+Z). The load compresses the liner
 * (thickness * pressure / modulus) and bends the structure. Returns the T-plate bottom's Z. */
static double bearing_branch(ModelInstance *comp, const double *dt, const double *a) {
    double *r = comp->v.r;
    double phase, cos_phase;
    /* the block's two lower halves stand side by side on the heel block: the axis rises with
     * their mean; heel block and bearing block each grow with their own coefficient */
    double heel = r[VR_h_heel_block] * dt[HEEL];
    double block = r[VR_h_bearing_block] * 0.5 * (dt[BBLOCK] + dt[BBLOCK_REAR]);
    r[VR_dz_bearing_block] = -(a[P_HEEL] * heel + a[P_BBLOCK] * block);
    bearing_block_tilt(comp->memo, r, dt, a[P_BBLOCK]);
    r[VR_dz_spindle] = a[P_SPINDLE] * r[VR_r_spindle] * dt[SPINDLE];
    r[VR_dz_bearing] = a[P_RINGS] * r[VR_t_bearing_rings] * dt[BEARING];
    r[VR_dz_t_plate] = a[P_TPLATE] * r[VR_l_t_plate] * dt[TPLATE];
    /* liner: elastic compression through its hysteresis, plus creep; structure: a compliance
     * that changes with the swing angle */
    r[VR_dz_liner_creep] = comp->v.m.creep;
    r[VR_dz_loading] = liner_play(comp, liner_elastic(comp)) + comp->v.m.creep +
                       r[VR_compliance_structure] *
                           (1.0 + r[VR_compliance_angle_factor] * (1.0 - memo_call(&comp->memo[MEMO_ANGLE_COS], cos, r[VR_angle]))) *
                           r[VR_radial_load];
    phase = r[VR_runout_phase];
    cos_phase = memo_call(&comp->memo[MEMO_RUNOUT_PHASE], cos, phase);
    r[VR_dz_runout] = r[VR_spindle_runout] * (memo_call(&comp->memo[MEMO_RUNOUT_COS], cos, r[VR_angle] - r[VR_runout_phase]) - cos_phase);
    r[VR_dz_vibration] = r[VR_vibration_z];
    r[VR_wear_depth_true] = comp->v.m.wear + r[VR_wear_offset];
    r[VR_z_t_plate] = r[VR_dz_bearing_block] + r[VR_dz_bearing_block_tilt] + r[VR_dz_spindle] + r[VR_dz_bearing] + r[VR_dz_t_plate] + r[VR_dz_loading] +
                      r[VR_dz_runout] + r[VR_dz_vibration] + r[VR_wear_depth_true];
    return r[VR_z_t_plate];
}

/* Thermal bending of the detecting frame: the bearing assembly's radiation (its rise over the
 * frame's mean rise) heats the frame's side face towards the probe (+X). Across the frame's width
 * w the faces differ by q w / k, so the curvature alpha (q w / k) / w = alpha q / k does not
 * depend on w; uniform along the frame hanging from the base, it turns the lower end by
 * kappa L. The warmer +X face is the longer one: the sensor's head, e beside the axis on the +X
 * side, goes down (+Z) by e * tilt. Rises since the start, as every thermal term. */
static void frame_bending(double *r, const double *dt) {
    double q = r[VR_h_radiation_frame] * r[VR_frame_view_factor] * (dt[BEARING] - 0.5 * (dt[FRAME] + dt[FRAME_LOWER]));
    r[VR_frame_tilt] = r[VR_alpha_detecting_frame] * q / r[VR_k_frame] * r[VR_l_detecting_frame];
    r[VR_dz_frame_bending] = r[VR_abbe_offset] * r[VR_frame_tilt];
}

/* Branch 2: the frame hangs from a face inset in the base (the base's material between its top
 * and that face grows with the base) and grows down, carrying the probe, whose body grows up
 * from its fixing to the tip; the pole grows down from its top (held on the T-plate) to the
 * clamp, and the clamp down to the head's contact face. */
static void detecting_branch(double *r, const double *dt, const double *a) {
    r[VR_dz_base_inset] = a[P_BASE] * r[VR_l_base_inset] * dt[BASE];
    r[VR_dz_probe_body] = -a[P_PROBE] * r[VR_l_probe_body] * dt[SENSOR];
    /* two lumps along the frame: each half grows with its own temperature */
    r[VR_dz_detecting_frame] = a[P_FRAME] * r[VR_l_detecting_frame] * 0.5 * (dt[FRAME] + dt[FRAME_LOWER]);
    r[VR_dz_long_pole] = a[P_POLE] * (r[VR_l_pole_heel] * dt[POLE_HEEL] + r[VR_l_pole_base] * dt[POLE_BASE] +
                                      r[VR_l_pole_lower] * dt[POLE_LOWER]);
    r[VR_dz_clamp] = a[P_CLAMP] * r[VR_l_clamp] * dt[CLAMP];
    frame_bending(r, dt);
    r[VR_z_sensor] = r[VR_dz_base_inset] + r[VR_dz_detecting_frame] + r[VR_dz_probe_body] + r[VR_dz_frame_bending];
}

/* Contact: with the pole top at z_top, the spring pushes up with f_spring0 + k_spring*z_top,
 * the head with f_head0 + k_head*(z_clamp - z_sensor), gravity pulls m g down. The net upward
 * force grows as the pole goes down. The pole follows the T-plate (at z_t) while that force
 * (the contact force) stays >= 0; otherwise the pole stops below the T-plate where the force
 * vanishes and a gap opens (lift-off is reported, not hidden). */
static void pole_contact(double *r, double z_t) {
    double k_total = r[VR_k_spring] + r[VR_k_head];
    double f_free = r[VR_f_spring0] + r[VR_f_head0] - r[VR_m_pole] * G_ACCEL;
    /* the head's force depends on the clamp relative to the sensor: fold the sensor's own
     * thermal motion and the pole/clamp growth into the equivalent pole-top position */
    double shift = r[VR_k_head] * (r[VR_dz_long_pole] + r[VR_dz_clamp] - r[VR_z_sensor]);
    double force_at_contact = f_free + r[VR_k_spring] * z_t + r[VR_k_head] * z_t + shift;
    if (force_at_contact >= 0.0) {
        r[VR_z_pole_top] = z_t;
        r[VR_contact_force] = force_at_contact;
        r[VR_pole_gap] = 0.0;
    } else {
        r[VR_z_pole_top] = -(f_free + shift) / k_total; /* below the T-plate, where the net force is zero */
        r[VR_contact_force] = 0.0;
        r[VR_pole_gap] = r[VR_z_pole_top] - z_t;
    }
    r[VR_lift_off] = r[VR_pole_gap] > 0.0 ? 1.0 : 0.0;
    r[VR_z_clamp] = r[VR_z_pole_top] + r[VR_dz_long_pole] + r[VR_dz_clamp];
}

/* Positioning: the friction torque turns the T-plate, and with it pole and clamp, by a small
 * angle; the probe, off the pole's axis by the Abbe offset, sees that as e*phi. Its axis,
 * tilted from Z by its mounting and by the frame's bending, reads the relative motion times
 * cos(tilt). */
static void probe_reading(Memo *memo, double *r) {
    double rotation = r[VR_tplate_rotation_compliance] * r[VR_friction_torque];
    double relative = r[VR_z_clamp] - r[VR_z_sensor];
    double tilt = r[VR_sensor_tilt] + r[VR_frame_tilt];
    double cos_tilt = memo_call(&memo[MEMO_PROBE_TILT], cos, tilt);
    double measured = (relative + r[VR_abbe_offset] * rotation) * cos_tilt;
    r[VR_tplate_rotation] = rotation;
    r[VR_dz_positioning] = measured - relative;
    r[VR_probe_true] = r[VR_probe_preload] + measured;
}

void model_outputs(ModelInstance *comp) {
    double *r = comp->v.r;
    double dt[FM_TEMPS], a[FM_PARTS], z_t;
    int i;

    /* all displacements are small, so each body's thermal term is linear in its dT; a part's
     * effective coefficient carries its mean-over-lump rise factor (x 1.0 exactly as lumped) */
    for (i = 0; i < FM_TEMPS; i++) dt[i] = r[VR_TEMPS[i]] - comp->v.m.t_ref[i];
    for (i = 0; i < FM_PARTS; i++) a[i] = r[VR_ALPHAS[i]] * r[VR_RISES[i]];
    z_t = bearing_branch(comp, dt, a);
    detecting_branch(r, dt, a);
    pole_contact(r, z_t);
    probe_reading(comp->memo, r);
    r[VR_wear_rate_now] = r[VR_wear_rate] * r[VR_contact_pressure] * r[VR_sliding_speed] *
                          (1.0 + r[VR_running_in_factor] *
                                     memo_call(&comp->memo[MEMO_RUNNING_IN], exp, -comp->v.m.sliding_distance / r[VR_running_in_distance]));
}

/* A state handed back: each reference temperature the one initialization takes (the input's
 * value at the start, within its range, or t_reference), the sliding distance between 0 and the
 * most the sliding speed's range allows over the elapsed time, the wear between 0 and the most
 * the Archard law gives over that distance at the highest contact pressure. */
int model_check_state(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    double elapsed = (double)comp->v.steps_taken * r[VR_solver_step];
    double s_max = real_var(VR_sliding_speed)->max * elapsed * (1.0 + 1e-6);
    double wear_max = r[VR_wear_rate] * real_var(VR_contact_pressure)->max *
                      (m->sliding_distance + r[VR_running_in_factor] * r[VR_running_in_distance]) * (1.0 + 1e-6);
    double el_max;
    int i;
    for (i = 0; i < FM_TEMPS; i++) {
        if (comp->v.b[VR_reference_at_start] ? state_bad_follower(c, "reference temperature", m->t_ref[i], VR_TEMPS[i])
                                             : state_bad_real(c, "reference temperature", m->t_ref[i], r[VR_t_reference],
                                                              r[VR_t_reference]))
            return -1;
    }
    /* the liner's compression can reach at most the largest load on a tenth of its modulus */
    el_max = r[VR_liner_thickness] / (0.1 * r[VR_liner_modulus] * r[VR_contact_area]) *
             real_var(VR_radial_load)->max * (1.0 + 1e-6);
    if (state_bad_real(c, "sliding_distance", m->sliding_distance, 0.0, s_max) ||
        state_bad_real(c, "wear", m->wear, 0.0, wear_max) ||
        state_bad_real(c, "creep", m->creep, -r[VR_liner_creep_ratio] * el_max, r[VR_liner_creep_ratio] * el_max) ||
        state_bad_real(c, "liner_play", m->liner_play, -el_max - r[VR_liner_hysteresis], el_max + r[VR_liner_hysteresis]))
        return -1;
    return 0;
}
