/* The Embree baseline of `lightvol bench --embree`: traces the rays lightvol traces, with
 * Embree 3's single-ray API (rtcIntersect1 / rtcOccluded1), and reports the best time of
 * several passes and every ray's result.
 *
 * Input (little-endian): "LVEB", u32 mode (0 closest hit, 1 occlusion), u32 threads,
 * u32 repeats, u32 isa (0: the kernels Embree picks for this CPU, 1: forced SSE2),
 * u32 triangle count n, f32 vertices[9 n], u32 ray count m, f32 rays[6 m] (origin,
 * direction), f32 tmax.
 * Standard output: Embree's own device report (verbose=1), which names the ISA targets it
 * supports here and was compiled for; the caller reads the one it runs from it.
 * Every thread that builds or traces runs with flush-to-zero and denormals-are-zero, as
 * Embree's performance recommendations ask.
 * Output: f64 best trace seconds, f64 build seconds, then f32 per ray: the hit distance or
 * -1 (closest), 1 or 0 (occlusion).
 *
 * Built by lightvol with the system C compiler against Debian's libembree-dev. */
#include <embree3/rtcore.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#if defined(__x86_64__) || defined(__i386__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif

/* Flush-to-zero and denormals-are-zero for the calling thread (Embree's recommendation). */
static void fast_denormals(void) {
#if defined(__x86_64__) || defined(__i386__)
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#endif
}

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void die(const char *msg) {
    fprintf(stderr, "embree_trace: %s\n", msg);
    exit(2);
}

static uint32_t read_u32(FILE *f) {
    uint32_t v;
    if (fread(&v, 4, 1, f) != 1) die("truncated input");
    return v;
}

struct job {
    RTCScene scene;
    const float *rays;
    float *out;
    size_t begin, end;
    float tmax;
    int mode;
};

static void *trace(void *arg) {
    struct job *j = arg;
    fast_denormals();
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (size_t i = j->begin; i < j->end; i++) {
        const float *r = j->rays + 6 * i;
        if (j->mode == 0) {
            struct RTCRayHit rh;
            rh.ray.org_x = r[0]; rh.ray.org_y = r[1]; rh.ray.org_z = r[2];
            rh.ray.dir_x = r[3]; rh.ray.dir_y = r[4]; rh.ray.dir_z = r[5];
            rh.ray.tnear = 0.0f; rh.ray.tfar = j->tmax; rh.ray.time = 0.0f;
            rh.ray.mask = 0xffffffffu; rh.ray.id = 0; rh.ray.flags = 0;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(j->scene, &ctx, &rh);
            j->out[i] = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? -1.0f : rh.ray.tfar;
        } else {
            struct RTCRay ray;
            ray.org_x = r[0]; ray.org_y = r[1]; ray.org_z = r[2];
            ray.dir_x = r[3]; ray.dir_y = r[4]; ray.dir_z = r[5];
            ray.tnear = 0.0f; ray.tfar = j->tmax; ray.time = 0.0f;
            ray.mask = 0xffffffffu; ray.id = 0; ray.flags = 0;
            rtcOccluded1(j->scene, &ctx, &ray);
            j->out[i] = ray.tfar == -INFINITY ? 1.0f : 0.0f;
        }
    }
    return NULL;
}

int main(int argc, char **argv) {
    if (argc != 3) die("usage: embree_trace IN OUT");
    FILE *f = fopen(argv[1], "rb");
    if (!f) die("cannot open the input");
    char magic[4];
    if (fread(magic, 1, 4, f) != 4 || memcmp(magic, "LVEB", 4) != 0) die("bad magic");
    int mode = (int)read_u32(f);
    uint32_t threads = read_u32(f), repeats = read_u32(f), isa = read_u32(f), n = read_u32(f);
    if (threads == 0 || threads > 256 || repeats == 0) die("bad thread or repeat count");
    if (isa > 1) die("bad isa");
    fast_denormals();
    float *verts = malloc((size_t)n * 9 * sizeof(float));
    if (!verts || fread(verts, sizeof(float), (size_t)n * 9, f) != (size_t)n * 9) die("truncated vertices");
    uint32_t m = read_u32(f);
    float *rays = malloc((size_t)m * 6 * sizeof(float));
    if (!rays || fread(rays, sizeof(float), (size_t)m * 6, f) != (size_t)m * 6) die("truncated rays");
    float tmax;
    if (fread(&tmax, 4, 1, f) != 1) die("truncated tmax");
    fclose(f);

    char config[64];
    snprintf(config, sizeof config, "threads=%u,verbose=1%s", threads, isa == 1 ? ",isa=sse2" : "");
    RTCDevice dev = rtcNewDevice(config);
    if (!dev) die("rtcNewDevice failed");
    RTCScene scene = rtcNewScene(dev);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), (size_t)n * 3);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n);
    if (!vb || !ib) die("geometry buffers");
    memcpy(vb, verts, (size_t)n * 9 * sizeof(float));
    for (uint32_t i = 0; i < 3 * n; i++) ib[i] = i;
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    double b0 = now();
    rtcCommitScene(scene);
    double build = now() - b0;

    float *out = calloc(m, sizeof(float));
    pthread_t tid[256];
    struct job jobs[256];
    double best = INFINITY;
    for (uint32_t rep = 0; rep < repeats; rep++) {
        double t0 = now();
        for (uint32_t t = 0; t < threads; t++) {
            jobs[t] = (struct job){scene, rays, out, (size_t)m * t / threads, (size_t)m * (t + 1) / threads, tmax, mode};
            if (pthread_create(&tid[t], NULL, trace, &jobs[t]) != 0) die("pthread_create");
        }
        for (uint32_t t = 0; t < threads; t++) pthread_join(tid[t], NULL);
        double dt = now() - t0;
        if (dt < best) best = dt;
    }
    FILE *o = fopen(argv[2], "wb");
    if (!o) die("cannot open the output");
    fwrite(&best, 8, 1, o);
    fwrite(&build, 8, 1, o);
    fwrite(out, sizeof(float), m, o);
    fclose(o);
    rtcReleaseScene(scene);
    rtcReleaseDevice(dev);
    free(verts);
    free(rays);
    free(out);
    return 0;
}
