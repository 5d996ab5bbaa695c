/* The FMI 2.0 functions of a flexmor body (model exchange and co-simulation), appended to the
   generated constants NX NU NY GUID and the arrays A B C D NOMINAL (row-major); for a body over a
   speed range SPIN_U and A1 A2; for a body with moving loads MOVING (paths), MOVING_U (the first
   force input: path k's force MOVING_U + 2 k, its position MOVING_U + 2 k + 1), NG (the generalized
   coordinates), NPATH, PATH_N PATH_AT (nodes per path, offset of its first), PATH_S (node arc
   lengths), PATH_B (NPATH x NG: per node the reduced input of a unit force) and G (NX x NG: the
   state-space input of a generalized force). */

/* ---- FMI 2.0 declarations (fmi2TypesPlatform.h, fmi2FunctionTypes.h) ---- */
typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
#define fmi2True 1
#define fmi2False 0

typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime, fmi2Terminated } fmi2StatusKind;

typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
typedef void *(*fmi2CallbackAllocateMemory)(size_t, size_t);
typedef void (*fmi2CallbackFreeMemory)(void *);
typedef void (*fmi2StepFinished)(fmi2ComponentEnvironment, fmi2Status);

typedef struct {
    const fmi2CallbackLogger logger;
    const fmi2CallbackAllocateMemory allocateMemory;
    const fmi2CallbackFreeMemory freeMemory;
    const fmi2StepFinished stepFinished;
    const fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef struct {
    fmi2Boolean newDiscreteStatesNeeded;
    fmi2Boolean terminateSimulation;
    fmi2Boolean nominalsOfContinuousStatesChanged;
    fmi2Boolean valuesOfContinuousStatesChanged;
    fmi2Boolean nextEventTimeDefined;
    fmi2Real nextEventTime;
} fmi2EventInfo;

#if defined(_WIN32)
#define FMI2_EXPORT __declspec(dllexport)
#else
#define FMI2_EXPORT
#endif

/* ---- value references: inputs, displacements, velocities, deflections under the moving loads, states,
   state derivatives ---- */
#ifndef MOVING
#define MOVING 0
#define NG 0
#endif
#define VR_Y NU
#define VR_V (NU + NY)
#define VR_L (NU + 2 * NY)
#define VR_X (VR_L + MOVING)
#define VR_DX (VR_X + NX)
#define N_VR (VR_DX + NX)
#define NW (NU + NG) /* the step's inputs: u and the moving loads' generalized force */
#define NA (NX + NW) /* the augmented matrix [[A, B, G], [0, 0, 0]] of the co-simulation step */
#define NU1 (NU > 0 ? NU : 1)

enum { INSTANTIATED, INITIALIZATION, RUNNING, TERMINATED, FAILED };

typedef struct {
    double time;
    double x[NX];
    double u[NU1];
    int mode;
} Snapshot;

typedef struct {
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2ComponentEnvironment environment;
    char *name;
    fmi2Type type;
    int loggingOn;
    Snapshot s;
    double h;      /* the step of phi and gam, 0 before the first step */
    double w;      /* the speed of phi and gam (a body over a speed range) */
    double *phi;   /* NX x NX: expm(A h) */
    double *gam;   /* NX x NW: int_0^h expm(A t) dt [B, G] */
    double *work;  /* 5 NA x NA + NA */
} Model;

static void logError(Model *m, const char *message) {
    if (m->logger != NULL)
        m->logger(m->environment, m->name, fmi2Error, "logStatusError", "%s", message);
}

#ifdef SPIN_U
/* a body over a speed range: A(w) = A + w A1 + w^2 A2, w the input SPIN_U (rad/s) */
static double a_at(const Model *m, int k) {
    double w = m->s.u[SPIN_U];
    return A[k] + w * A1[k] + w * w * A2[k];
}
#else
#define a_at(m, k) A[k]
#endif

#if MOVING > 0
/* the segment [PATH_S[j], PATH_S[j + 1]] of path k that the position s lies on (bisection) and the share t of
   its node j + 1 (1 - t of node j); -1 for a position off the path (or not a number) */
static int segment(int k, double s, double *t) {
    const double *p = PATH_S + PATH_AT[k];
    int lo = 0, hi = PATH_N[k] - 1;
    if (!(s >= p[0] && s <= p[hi])) return -1;
    while (hi - lo > 1) {
        int mid = lo + (hi - lo) / 2;
        if (p[mid] <= s) lo = mid;
        else hi = mid;
    }
    *t = (s - p[lo]) / (p[lo + 1] - p[lo]);
    return lo;
}

/* b := B_path w(s) of path k at its position input: NG entries, 0 off the path; returns 0 there, else 1 */
static int path_column(const Model *m, int k, double *b) {
    double t = 0.0;
    int i, j = segment(k, m->s.u[MOVING_U + 2 * k + 1], &t);
    const double *lo;
    if (j < 0) return 0;
    lo = PATH_B + (size_t)(PATH_AT[k] + j) * NG;
    for (i = 0; i < NG; i++) b[i] = (1.0 - t) * lo[i] + t * lo[NG + i];
    return 1;
}

/* g := the generalized force of the moving loads, sum over the paths of B_path w(s) F */
static void path_forces(const Model *m, double *g) {
    double b[NG];
    int i, k;
    for (i = 0; i < NG; i++) g[i] = 0.0;
    for (k = 0; k < MOVING; k++) {
        double f = m->s.u[MOVING_U + 2 * k];
        if (path_column(m, k, b))
            for (i = 0; i < NG; i++) g[i] += f * b[i];
    }
}

/* the deflection under the load of path k: w(s)^T B_path^T q (q the first NG states) */
static double under_load(const Model *m, int k) {
    double b[NG], y = 0.0;
    int i;
    if (!path_column(m, k, b)) return 0.0;
    for (i = 0; i < NG; i++) y += b[i] * m->s.x[i];
    return y;
}
#endif

static void derivatives(const Model *m, double *dx) {
    int i, j;
#if MOVING > 0
    double g[NG];
    path_forces(m, g);
#endif
    for (i = 0; i < NX; i++) {
        double s = 0.0;
        for (j = 0; j < NX; j++) s += a_at(m, i * NX + j) * m->s.x[j];
        for (j = 0; j < NU; j++) s += B[i * NU + j] * m->s.u[j];
#if MOVING > 0
        for (j = 0; j < NG; j++) s += G[i * NG + j] * g[j];
#endif
        dx[i] = s;
    }
}

static double displacement(const Model *m, int k) {
    int j;
    double s = 0.0;
    for (j = 0; j < NX; j++) s += C[k * NX + j] * m->s.x[j];
    for (j = 0; j < NU; j++) s += D[k * NU + j] * m->s.u[j];
    return s;
}

static double velocity(int k, const double *dx) {
    int j;
    double s = 0.0;
    for (j = 0; j < NX; j++) s += C[k * NX + j] * dx[j];
    return s;
}

/* ---- matrix exponential: balancing, scaling and squaring, diagonal Pade approximant of degree 6 ---- */

static void matmul(int n, const double *a, const double *b, double *c) {
    int i, j, k;
    for (i = 0; i < n * n; i++) c[i] = 0.0;
    for (i = 0; i < n; i++)
        for (k = 0; k < n; k++) {
            double aik = a[i * n + k];
            if (aik == 0.0) continue;
            for (j = 0; j < n; j++) c[i * n + j] += aik * b[k * n + j];
        }
}

/* p x = q for n right-hand sides (q overwritten by x, p by its LU factors); 0 on success */
static int solve(int n, double *p, double *q) {
    int i, j, k;
    for (k = 0; k < n; k++) {
        int piv = k;
        double big = fabs(p[k * n + k]);
        for (i = k + 1; i < n; i++)
            if (fabs(p[i * n + k]) > big) { big = fabs(p[i * n + k]); piv = i; }
        if (!(big > 0.0)) return -1;
        if (piv != k)
            for (j = 0; j < n; j++) {
                double t = p[k * n + j]; p[k * n + j] = p[piv * n + j]; p[piv * n + j] = t;
                t = q[k * n + j]; q[k * n + j] = q[piv * n + j]; q[piv * n + j] = t;
            }
        for (i = k + 1; i < n; i++) {
            double f = p[i * n + k] / p[k * n + k];
            if (f == 0.0) continue;
            for (j = k + 1; j < n; j++) p[i * n + j] -= f * p[k * n + j];
            for (j = 0; j < n; j++) q[i * n + j] -= f * q[k * n + j];
        }
    }
    for (k = n - 1; k >= 0; k--)
        for (j = 0; j < n; j++) {
            double s = q[k * n + j];
            for (i = k + 1; i < n; i++) s -= p[k * n + i] * q[i * n + j];
            q[k * n + j] = s / p[k * n + k];
        }
    return 0;
}

/* a := d^-1 a d with d a diagonal of powers of 2 that equalizes row and column norms (Parlett-Reinsch) */
static void balance(int n, double *a, double *d) {
    int i, j, sweep, done = 0;
    for (i = 0; i < n; i++) d[i] = 1.0;
    for (sweep = 0; sweep < 100 && !done; sweep++) {
        done = 1;
        for (i = 0; i < n; i++) {
            double c = 0.0, r = 0.0, f = 1.0, g, s;
            for (j = 0; j < n; j++)
                if (j != i) { c += fabs(a[j * n + i]); r += fabs(a[i * n + j]); }
            if (c == 0.0 || r == 0.0) continue;
            s = c + r;
            g = r / 2.0;
            while (c < g && f < 1e150) { f *= 2.0; c *= 4.0; }
            g = r * 2.0;
            while (c >= g && f > 1e-150) { f /= 2.0; c /= 4.0; }
            if ((c + r) / f < 0.95 * s) {
                done = 0;
                d[i] *= f;
                for (j = 0; j < n; j++) { a[i * n + j] /= f; a[j * n + i] *= f; }
            }
        }
    }
}

/* a := expm(a), n x n; w holds 5 n x n + n doubles; 0 on success */
static int expm(int n, double *a, double *w) {
    double *x = w, *t = w + n * n, *num = w + 2 * n * n, *den = w + 3 * n * n, *e = w + 4 * n * n, *d = w + 5 * n * n;
    double norm = 0.0, c = 0.5;
    int i, j, k, s = 0;
    const int q = 6;
    balance(n, a, d);
    for (i = 0; i < n; i++) {
        double r = 0.0;
        for (j = 0; j < n; j++) r += fabs(a[i * n + j]);
        if (r > norm) norm = r;
    }
    if (!(norm < 1e300)) return -1;
    if (norm > 0.5) {
        frexp(norm / 0.5, &s);
        for (i = 0; i < n * n; i++) a[i] = ldexp(a[i], -s);
    }
    for (i = 0; i < n * n; i++) {
        x[i] = a[i];
        num[i] = c * a[i];
        den[i] = -c * a[i];
    }
    for (i = 0; i < n; i++) { num[i * n + i] += 1.0; den[i * n + i] += 1.0; }
    for (k = 2; k <= q; k++) {
        c = c * (q - k + 1) / (k * (2 * q - k + 1));
        matmul(n, a, x, t);
        for (i = 0; i < n * n; i++) {
            x[i] = t[i];
            num[i] += c * t[i];
            den[i] += (k % 2 == 0 ? c : -c) * t[i];
        }
    }
    if (solve(n, den, num) != 0) return -1;
    for (k = 0; k < s; k++) {
        matmul(n, num, num, e);
        for (i = 0; i < n * n; i++) num[i] = e[i];
    }
    for (i = 0; i < n; i++)
        for (j = 0; j < n; j++) a[i * n + j] = num[i * n + j] * d[i] / d[j];
    return 0;
}

/* phi, gam of the step h: expm([[A, B, G], [0, 0, 0]] h) = [[phi, gam], [0, I]] */
static int discretize(Model *m, double h) {
    double *a = m->work + 5 * NA * NA + NA;
    int i, j;
    for (i = 0; i < NA * NA; i++) a[i] = 0.0;
    for (i = 0; i < NX; i++) {
        for (j = 0; j < NX; j++) a[i * NA + j] = a_at(m, i * NX + j) * h;
        for (j = 0; j < NU; j++) a[i * NA + NX + j] = B[i * NU + j] * h;
#if MOVING > 0
        for (j = 0; j < NG; j++) a[i * NA + NX + NU + j] = G[i * NG + j] * h;
#endif
    }
    if (expm(NA, a, m->work) != 0) return -1;
    for (i = 0; i < NX; i++) {
        for (j = 0; j < NX; j++) m->phi[i * NX + j] = a[i * NA + j];
        for (j = 0; j < NW; j++) m->gam[i * NW + j] = a[i * NA + NX + j];
    }
    m->h = h;
#ifdef SPIN_U
    m->w = m->s.u[SPIN_U];
#endif
    return 0;
}

/* ---- common functions ---- */

FMI2_EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
FMI2_EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

FMI2_EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                           const fmi2String categories[]) {
    (void)nCategories; (void)categories;
    if (c == NULL) return fmi2Error;
    ((Model *)c)->loggingOn = loggingOn;
    return fmi2OK;
}

static void *allocate(Model *m, size_t n, size_t size) {
    return m->allocateMemory(n > 0 ? n : 1, size);
}

FMI2_EXPORT void fmi2FreeInstance(fmi2Component c);

FMI2_EXPORT fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean loggingOn) {
    Model *m;
    (void)fmuResourceLocation; (void)visible;
    if (functions == NULL || functions->allocateMemory == NULL || functions->freeMemory == NULL) return NULL;
    if (instanceName == NULL) instanceName = "";
    if (fmuGUID == NULL || strcmp(fmuGUID, GUID) != 0) {
        if (functions->logger != NULL)
            functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                              "the GUID %s is not the one of this binary, %s", fmuGUID ? fmuGUID : "(null)", GUID);
        return NULL;
    }
    m = (Model *)functions->allocateMemory(1, sizeof(Model));
    if (m == NULL) return NULL;
    m->logger = functions->logger;
    m->allocateMemory = functions->allocateMemory;
    m->freeMemory = functions->freeMemory;
    m->environment = functions->componentEnvironment;
    m->type = fmuType;
    m->loggingOn = loggingOn;
    m->name = (char *)allocate(m, strlen(instanceName) + 1, 1);
    if (m->name != NULL) strcpy(m->name, instanceName);
    if (fmuType == fmi2CoSimulation) {
        m->phi = (double *)allocate(m, NX * NX, sizeof(double));
        m->gam = (double *)allocate(m, NX * NW, sizeof(double));
        m->work = (double *)allocate(m, 6 * NA * NA + NA, sizeof(double));
        if (m->phi == NULL || m->gam == NULL || m->work == NULL) {
            fmi2FreeInstance(m);
            return NULL;
        }
    }
    m->s.mode = INSTANTIATED;
    return m;
}

FMI2_EXPORT void fmi2FreeInstance(fmi2Component c) {
    Model *m = (Model *)c;
    if (m == NULL) return;
    if (m->name) m->freeMemory(m->name);
    if (m->phi) m->freeMemory(m->phi);
    if (m->gam) m->freeMemory(m->gam);
    if (m->work) m->freeMemory(m->work);
    m->freeMemory(m);
}

FMI2_EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                                           fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (c == NULL) return fmi2Error;
    ((Model *)c)->s.time = startTime;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    ((Model *)c)->s.mode = INITIALIZATION;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    ((Model *)c)->s.mode = RUNNING;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2Terminate(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    ((Model *)c)->s.mode = TERMINATED;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    Model *m = (Model *)c;
    if (m == NULL) return fmi2Error;
    memset(&m->s, 0, sizeof(Snapshot));
    m->s.mode = INSTANTIATED;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Model *m = (Model *)c;
    double dx[NX];
    int have_dx = 0;
    size_t k;
    if (m == NULL || (nvr > 0 && (vr == NULL || value == NULL))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        long r = (long)vr[k];
        if ((r >= VR_V && r < VR_L) || (r >= VR_DX && r < N_VR)) {
            if (!have_dx) { derivatives(m, dx); have_dx = 1; }
        }
        if (r < VR_Y) value[k] = m->s.u[r];
        else if (r < VR_V) value[k] = displacement(m, (int)(r - VR_Y));
        else if (r < VR_L) value[k] = velocity((int)(r - VR_V), dx);
#if MOVING > 0
        else if (r < VR_X) value[k] = under_load(m, (int)(r - VR_L));
#endif
        else if (r < VR_DX) value[k] = m->s.x[r - VR_X];
        else if (r < N_VR) value[k] = dx[r - VR_DX];
        else {
            logError(m, "fmi2GetReal: unknown value reference");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
    Model *m = (Model *)c;
    size_t k;
    if (m == NULL || (nvr > 0 && (vr == NULL || value == NULL))) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        long r = (long)vr[k];
        if (r < VR_Y) m->s.u[r] = value[k];
        else if (r >= VR_X && r < VR_DX && (m->s.mode == INSTANTIATED || m->s.mode == INITIALIZATION))
            m->s.x[r - VR_X] = value[k];
        else {
            logError(m, "fmi2SetReal: only the inputs, and the states before initialization, can be set");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

static fmi2Status noValues(fmi2Component c, size_t nvr, const char *message) {
    if (nvr == 0) return fmi2OK;
    if (c != NULL) logError((Model *)c, message);
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Integer value[]) {
    (void)vr; (void)value;
    return noValues(c, nvr, "fmi2GetInteger: the model has no Integer variable");
}

FMI2_EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      fmi2Boolean value[]) {
    (void)vr; (void)value;
    return noValues(c, nvr, "fmi2GetBoolean: the model has no Boolean variable");
}

FMI2_EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     fmi2String value[]) {
    (void)vr; (void)value;
    return noValues(c, nvr, "fmi2GetString: the model has no String variable");
}

FMI2_EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Integer value[]) {
    (void)vr; (void)value;
    return noValues(c, nvr, "fmi2SetInteger: the model has no Integer variable");
}

FMI2_EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                      const fmi2Boolean value[]) {
    (void)vr; (void)value;
    return noValues(c, nvr, "fmi2SetBoolean: the model has no Boolean variable");
}

FMI2_EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                     const fmi2String value[]) {
    (void)vr; (void)value;
    return noValues(c, nvr, "fmi2SetString: the model has no String variable");
}

FMI2_EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Model *m = (Model *)c;
    if (m == NULL || state == NULL) return fmi2Error;
    if (*state == NULL) *state = m->allocateMemory(1, sizeof(Snapshot));
    if (*state == NULL) return fmi2Error;
    memcpy(*state, &m->s, sizeof(Snapshot));
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Model *m = (Model *)c;
    if (m == NULL || state == NULL) return fmi2Error;
    memcpy(&m->s, state, sizeof(Snapshot));
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Model *m = (Model *)c;
    if (m == NULL || state == NULL) return fmi2Error;
    if (*state != NULL) m->freeMemory(*state);
    *state = NULL;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)state;
    if (c == NULL || size == NULL) return fmi2Error;
    *size = sizeof(Snapshot);
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size) {
    if (c == NULL || state == NULL || bytes == NULL || size < sizeof(Snapshot)) return fmi2Error;
    memcpy(bytes, state, sizeof(Snapshot));
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                               fmi2FMUstate *state) {
    Model *m = (Model *)c;
    if (m == NULL || bytes == NULL || state == NULL || size != sizeof(Snapshot)) return fmi2Error;
    if (*state == NULL) *state = m->allocateMemory(1, sizeof(Snapshot));
    if (*state == NULL) return fmi2Error;
    memcpy(*state, bytes, sizeof(Snapshot));
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                                    size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                                    size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    if (c != NULL) logError((Model *)c, "fmi2GetDirectionalDerivative is not provided");
    return fmi2Error;
}

/* ---- model exchange ---- */

FMI2_EXPORT fmi2Status fmi2EnterEventMode(fmi2Component c) { return c == NULL ? fmi2Error : fmi2OK; }

FMI2_EXPORT fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    if (c == NULL || info == NULL) return fmi2Error;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return c == NULL ? fmi2Error : fmi2OK; }

FMI2_EXPORT fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL || enterEventMode == NULL || terminateSimulation == NULL) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    if (c == NULL) return fmi2Error;
    ((Model *)c)->s.time = time;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Model *m = (Model *)c;
    if (m == NULL || nx != NX || x == NULL) return fmi2Error;
    memcpy(m->s.x, x, NX * sizeof(double));
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivs[], size_t nx) {
    if (c == NULL || nx != NX || derivs == NULL) return fmi2Error;
    derivatives((Model *)c, derivs);
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators;
    return c == NULL || ni != 0 ? fmi2Error : fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Model *m = (Model *)c;
    if (m == NULL || nx != NX || x == NULL) return fmi2Error;
    memcpy(x, m->s.x, NX * sizeof(double));
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    if (c == NULL || nx != NX || x_nominal == NULL) return fmi2Error;
    memcpy(x_nominal, NOMINAL, NX * sizeof(double));
    return fmi2OK;
}

/* ---- co-simulation ---- */

FMI2_EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)order; (void)value;
    return noValues(c, nvr, "fmi2SetRealInputDerivatives: the inputs are held over a step (no interpolation)");
}

FMI2_EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                    const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)order; (void)value;
    return noValues(c, nvr, "fmi2GetRealOutputDerivatives is not provided");
}

FMI2_EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Model *m = (Model *)c;
    double xn[NX];
    int i, j;
#if MOVING > 0
    double g[NG];
#endif
    (void)noSetFMUStatePriorToCurrentPoint;
    if (m == NULL) return fmi2Error;
    if (m->type != fmi2CoSimulation || m->s.mode != RUNNING) {
        logError(m, "fmi2DoStep: not an initialized co-simulation instance");
        return fmi2Error;
    }
    if (!(communicationStepSize >= 0.0) || !(communicationStepSize < 1e300)) {
        logError(m, "fmi2DoStep: the communication step size must be a finite number >= 0");
        return fmi2Error;
    }
    if (communicationStepSize > 0.0) {
#ifdef SPIN_U
        int moved = m->s.u[SPIN_U] != m->w; /* another speed: another exponential */
#else
        int moved = 0;
#endif
        if ((communicationStepSize != m->h || moved) && discretize(m, communicationStepSize) != 0) {
            m->h = 0.0;
            logError(m, "fmi2DoStep: the matrix exponential of the step failed");
            return fmi2Error;
        }
#if MOVING > 0
        path_forces(m, g); /* the loads' force and position held over the step: a constant generalized force */
#endif
        for (i = 0; i < NX; i++) {
            double s = 0.0;
            for (j = 0; j < NX; j++) s += m->phi[i * NX + j] * m->s.x[j];
            for (j = 0; j < NU; j++) s += m->gam[i * NW + j] * m->s.u[j];
#if MOVING > 0
            for (j = 0; j < NG; j++) s += m->gam[i * NW + NU + j] * g[j];
#endif
            xn[i] = s;
        }
        memcpy(m->s.x, xn, NX * sizeof(double));
    }
    m->s.time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2CancelStep(fmi2Component c) {
    (void)c;
    return fmi2Error;
}

FMI2_EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    if (c == NULL || value == NULL || s != fmi2DoStepStatus) return fmi2Discard;
    *value = fmi2OK;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (c == NULL || value == NULL || s != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = ((Model *)c)->s.time;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}

FMI2_EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (c == NULL || value == NULL || s != fmi2Terminated) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

FMI2_EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)c; (void)s; (void)value;
    return fmi2Discard;
}
