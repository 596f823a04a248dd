/* The SUNDIALS CVODES interface that softcurve's driver calls: the copy inside CasADi's
 * plugin libcasadi_integrator_cvodes.so, SUNDIALS 2.x (the interface before SUNDIALS 3's
 * SUNLinearSolver: iterative linear solvers of the CVSPILS family, CVSpgmr), as bundled
 * by CasADi 3.8, the version the driver was verified with. Declared by hand because the
 * plugin ships no headers; the prototypes and constants are those of SUNDIALS 2.x's
 * cvodes.h, cvodes_spils.h, cvodes_spgmr.h, nvector_serial.h and sundials_iterative.h.
 * The driver refuses a plugin without CVSpgmr (SUNDIALS 3 and later have another
 * interface) and a CasADi outside the versions it was verified with (softcurve's casadi
 * requirement). */
#ifndef SOFTCURVE_SUNDIALS2_H
#define SOFTCURVE_SUNDIALS2_H

typedef double realtype;
typedef struct _generic_N_Vector *N_Vector;
typedef int (*CVRhsFn)(realtype t, N_Vector y, N_Vector ydot, void *data);
typedef int (*CVPrecSetupFn)(realtype t, N_Vector y, N_Vector fy, int jok, int *jcur,
                             realtype gamma, void *data, N_Vector t1, N_Vector t2, N_Vector t3);
typedef int (*CVPrecSolveFn)(realtype t, N_Vector y, N_Vector fy, N_Vector r, N_Vector z,
                             realtype gamma, realtype delta, int lr, void *data, N_Vector tmp);
typedef int (*CVJacTimesFn)(N_Vector v, N_Vector Jv, realtype t, N_Vector y, N_Vector fy,
                            void *data, N_Vector tmp);
typedef void (*CVErrHandlerFn)(int code, const char *module, const char *function, char *msg,
                               void *data);
typedef int (*CVSensRhsFn)(int Ns, realtype t, N_Vector y, N_Vector ydot, N_Vector *yS,
                           N_Vector *ySdot, void *data, N_Vector tmp1, N_Vector tmp2);

extern N_Vector N_VNew_Serial(long int length);
extern realtype *N_VGetArrayPointer(N_Vector v);
extern void N_VDestroy(N_Vector v);
extern N_Vector *N_VCloneVectorArray_Serial(int count, N_Vector w);
extern void N_VDestroyVectorArray_Serial(N_Vector *vs, int count);
extern void *CVodeCreate(int lmm, int iter);
extern int CVodeInit(void *mem, CVRhsFn f, realtype t0, N_Vector y0);
extern int CVodeReInit(void *mem, realtype t0, N_Vector y0);
extern int CVodeSStolerances(void *mem, realtype rtol, realtype atol);
extern int CVodeSVtolerances(void *mem, realtype rtol, N_Vector atol);
extern int CVodeSetUserData(void *mem, void *data);
extern int CVodeSetMaxNumSteps(void *mem, long int mxsteps);
extern int CVodeSetMaxOrd(void *mem, int maxord);
extern int CVodeSetStopTime(void *mem, realtype tstop);
extern int CVodeGetDky(void *mem, realtype t, int k, N_Vector dky);
extern int CVodeSetErrHandlerFn(void *mem, CVErrHandlerFn f, void *data);
extern int CVode(void *mem, realtype tout, N_Vector yout, realtype *tret, int itask);
extern int CVodeGetNumSteps(void *mem, long int *n);
extern int CVodeGetLastOrder(void *mem, int *qlast);
extern int CVodeGetNumRhsEvals(void *mem, long int *n);
extern int CVodeGetNumLinSolvSetups(void *mem, long int *n);
extern int CVodeGetNumErrTestFails(void *mem, long int *n);
extern int CVodeGetNumNonlinSolvConvFails(void *mem, long int *n);
extern void CVodeFree(void **mem);
extern int CVSpgmr(void *mem, int pretype, int maxl);
extern int CVSpilsSetPreconditioner(void *mem, CVPrecSetupFn setup, CVPrecSolveFn solve);
extern int CVSpilsSetJacTimesVecFn(void *mem, CVJacTimesFn jtimes);
extern int CVodeSensInit(void *mem, int Ns, int ism, CVSensRhsFn fS, N_Vector *yS0);
extern int CVodeSensReInit(void *mem, int ism, N_Vector *yS0);
extern int CVodeSensEEtolerances(void *mem);
extern int CVodeSetSensErrCon(void *mem, int errconS);
extern int CVodeGetSens(void *mem, realtype *tret, N_Vector *yS);

#define CV_ADAMS 1
#define CV_BDF 2
#define CV_NEWTON 2
#define CV_NORMAL 1
#define CV_ONE_STEP 2
#define CV_STAGGERED 2
#define CV_TSTOP_RETURN 1
#define CV_TOO_MUCH_WORK -1
#define CV_ERR_FAILURE -3
#define CV_CONV_FAILURE -4
#define CV_LSETUP_FAIL -6
#define CV_RHSFUNC_FAIL -8
#define CV_FIRST_RHSFUNC_ERR -9
#define PREC_LEFT 1

#endif
