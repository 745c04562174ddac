/*
 * Embree 3 (Debian's libembree-dev) on the rays path mode traces, batch by batch:
 *
 *   RT_PATHRAYS_DUMP=rays.bin raytracer render SCENE -j 1 -o x.png   (a local build
 *       with the dump hook of bench/pathrays/README.md)
 *   bench/pathrays/embree_pathrays rays.bin [--repeat N] [--threads T] [--high] [--robust]
 *       [--buckets] [--shuffle] [--only KIND:GROUP [--first N]]
 *
 * Builds the file's triangles (RTC_BUILD_QUALITY_MEDIUM unless --high), then traces
 * each group of batches (closest hit or any hit; camera rays and the first step's
 * shadow rays, the first bounce, deeper bounces) as 16-wide packets with the batch's
 * active lanes valid (rtcIntersect16 / rtcOccluded16, as Mitsuba's sixteen-lane
 * LLVM kernels call Embree) and as single rays (rtcIntersect1 / rtcOccluded1), on T
 * OpenMP threads. Prints, per group and mode, the median CPU seconds and Mrays per
 * CPU-second, and one JSON line. With --buckets, each group apart by its batches'
 * active lanes (1-4, 5-8, 9-12, 13-16); with --shuffle, each group's batches in a
 * fixed random order instead of the order path mode traced them.
 *
 * With --only KIND:GROUP (KIND 0 closest, 1 any; GROUP 0 camera rays and their
 * shadow rays, 1 first bounce, 2 bounces 2-7), only that group's single rays, its
 * first N active rays in file order (--first N), one after another on the calling
 * thread in trace_single_rays (not inlined: `valgrind --tool=callgrind
 * --toggle-collect=trace_single_rays` counts the tracing alone), --repeat times;
 * prints rays, hits and Mrays per CPU-second. Against a build of Embree with
 * EMBREE_STAT_COUNTERS (bench/embree/count.sh) its counters are then this group's.
 *
 * The file, little-endian: "RTPATH01", u32 vertex count, f32 x y z each, u32
 * triangle count, u32 a b c each, then batches to the end: u8 kind (0 closest,
 * 1 any), u8 step (0 = camera rays and their shadow rays), u16 0, u32 active lanes,
 * 16 x (f32 ox oy oz dx dy dz tmax).
 *
 * Build: cc -O3 -march=native -fopenmp embree_pathrays.c -lembree3 -o embree_pathrays
 * Against Mitsuba's own Embree (3.13.4, in its Python package as libembree3.so,
 * its API in namespace `mitsuba`), M being that package's folder:
 *   c++ -x c++ -O3 -march=native -fopenmp -I$M/include embree_pathrays.c -x none $M/libembree3.so \
 *       -Wl,-rpath,$M -o embree_pathrays_mitsuba
 */
#include <embree3/rtcore.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Mitsuba's own Embree (its libembree3.so, built in namespace `mitsuba`) when built
 * as C++ against its headers; nothing with Debian's. */
RTC_NAMESPACE_USE

typedef struct {
    float o[3], d[3], tmax;
} Ray;

typedef struct {
    uint8_t kind, step;
    uint16_t zero;
    uint32_t active;
    Ray rays[16];
} Batch;

static void die(const char *message) {
    fprintf(stderr, "embree_pathrays: error: %s\n", message);
    exit(2);
}

static double cpu_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

static int compare(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static RTCScene scene;

static long trace(const Batch *const *batches, long n, int packets) {
    long found = 0;
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : found)
    for (long i = 0; i < n; i++) {
        const Batch *b = batches[i];
        struct RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        if (packets) {
            RTC_ALIGN(64) int valid[16];
            RTC_ALIGN(64) struct RTCRayHit16 rh;
            for (int l = 0; l < 16; l++) {
                const Ray *r = &b->rays[l];
                valid[l] = (b->active >> l & 1) ? -1 : 0;
                rh.ray.org_x[l] = r->o[0];
                rh.ray.org_y[l] = r->o[1];
                rh.ray.org_z[l] = r->o[2];
                rh.ray.dir_x[l] = r->d[0];
                rh.ray.dir_y[l] = r->d[1];
                rh.ray.dir_z[l] = r->d[2];
                rh.ray.tnear[l] = 0.0f;
                rh.ray.tfar[l] = r->tmax;
                rh.ray.time[l] = 0.0f;
                rh.ray.mask[l] = 0xFFFFFFFF;
                rh.ray.id[l] = 0;
                rh.ray.flags[l] = 0;
                rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
            }
            if (b->kind == 0) {
                rtcIntersect16(valid, scene, &context, &rh);
                for (int l = 0; l < 16; l++)
                    found += valid[l] && rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
            } else {
                rtcOccluded16(valid, scene, &context, &rh.ray);
                for (int l = 0; l < 16; l++) found += valid[l] && rh.ray.tfar[l] < 0.0f;
            }
            continue;
        }
        for (int l = 0; l < 16; l++) {
            if (!(b->active >> l & 1)) continue;
            const Ray *r = &b->rays[l];
            struct RTCRayHit rh;
            rh.ray.org_x = r->o[0];
            rh.ray.org_y = r->o[1];
            rh.ray.org_z = r->o[2];
            rh.ray.dir_x = r->d[0];
            rh.ray.dir_y = r->d[1];
            rh.ray.dir_z = r->d[2];
            rh.ray.tnear = 0.0f;
            rh.ray.tfar = r->tmax;
            rh.ray.time = 0.0f;
            rh.ray.mask = 0xFFFFFFFF;
            rh.ray.id = 0;
            rh.ray.flags = 0;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            if (b->kind == 0) {
                rtcIntersect1(scene, &context, &rh);
                found += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
            } else {
                rtcOccluded1(scene, &context, &rh.ray);
                found += rh.ray.tfar < 0.0f;
            }
        }
    }
    return found;
}

/* One ray after another, as the replay's single rays (RT_PATHRAYS_ONLY). */
__attribute__((noinline)) static long trace_single_rays(const Ray *rays, long n, int kind) {
    long found = 0;
    struct RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (long i = 0; i < n; i++) {
        const Ray *r = &rays[i];
        struct RTCRayHit rh;
        rh.ray.org_x = r->o[0];
        rh.ray.org_y = r->o[1];
        rh.ray.org_z = r->o[2];
        rh.ray.dir_x = r->d[0];
        rh.ray.dir_y = r->d[1];
        rh.ray.dir_z = r->d[2];
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = r->tmax;
        rh.ray.time = 0.0f;
        rh.ray.mask = 0xFFFFFFFF;
        rh.ray.id = 0;
        rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        if (kind == 0) {
            rtcIntersect1(scene, &context, &rh);
            found += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        } else {
            rtcOccluded1(scene, &context, &rh.ray);
            found += rh.ray.tfar < 0.0f;
        }
    }
    return found;
}

/* --only: the first `first` active rays of one group, traced singly on this thread. */
static void only_group(const Batch *all, size_t count, int kind, int group, long first, int repeat) {
    Ray *rays = (Ray *)malloc((first > 0 ? (size_t)first : count * 16) * sizeof(Ray));
    long n = 0;
    if (!rays) die("out of memory");
    for (size_t i = 0; i < count && (first <= 0 || n < first); i++) {
        int step = all[i].step < 2 ? all[i].step : 2;
        if (all[i].kind != kind || step != group) continue;
        for (int l = 0; l < 16 && (first <= 0 || n < first); l++)
            if (all[i].active >> l & 1) rays[n++] = all[i].rays[l];
    }
    double cpus[100];
    long found = 0;
    for (int run = 0; run < repeat; run++) {
        double c0 = cpu_now();
        found = trace_single_rays(rays, n, kind);
        cpus[run] = cpu_now() - c0;
    }
    qsort(cpus, repeat, sizeof(double), compare);
    printf("{\"kind\": %d, \"group\": %d, \"rays\": %ld, \"found\": %ld, \"single_mrays\": %.4f}\n", kind,
           group, n, found, n / cpus[repeat / 2] * 1e-6);
    free(rays);
}

int main(int argc, char **argv) {
    const char *path = NULL;
    int repeat = 3, threads = 2, high = 0, robust = 0, buckets = 0, shuffle = 0;
    int only_kind = -1, only_group_ = -1;
    long first = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--repeat") && i + 1 < argc)
            repeat = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--high"))
            high = 1;
        else if (!strcmp(argv[i], "--robust"))
            robust = 1;
        else if (!strcmp(argv[i], "--buckets"))
            buckets = 1;
        else if (!strcmp(argv[i], "--shuffle"))
            shuffle = 1;
        else if (!strcmp(argv[i], "--only") && i + 1 < argc) {
            if (sscanf(argv[++i], "%d:%d", &only_kind, &only_group_) != 2 || only_kind < 0 || only_kind > 1 ||
                only_group_ < 0 || only_group_ > 2)
                die("--only takes KIND:GROUP, KIND 0 or 1, GROUP 0 to 2");
        } else if (!strcmp(argv[i], "--first") && i + 1 < argc)
            first = atol(argv[++i]);
        else if (argv[i][0] != '-' && !path)
            path = argv[i];
        else
            die("usage: embree_pathrays RAYS.bin [--repeat N] [--threads T] [--high] [--robust]");
    }
    if (!path || repeat < 1 || repeat > 100 || threads < 1)
        die("usage: embree_pathrays RAYS.bin [--repeat N] [--threads T] [--high] [--robust]");
    FILE *in = fopen(path, "rb");
    if (!in) die("cannot open the rays file");
    char magic[8];
    uint32_t nv, nt;
    if (fread(magic, 1, 8, in) != 8 || memcmp(magic, "RTPATH01", 8)) die("not a path rays file");
    if (fread(&nv, 4, 1, in) != 1 || nv > (1u << 28)) die("bad vertex count");
    float *vertices = (float *)aligned_alloc(64, ((size_t)nv * 12 + 16 + 63) / 64 * 64);
    if (!vertices || fread(vertices, 12, nv, in) != nv) die("truncated vertices");
    if (fread(&nt, 4, 1, in) != 1 || nt > (1u << 28)) die("bad triangle count");
    uint32_t *triangles = (uint32_t *)aligned_alloc(64, ((size_t)nt * 12 + 63) / 64 * 64);
    if (!triangles || fread(triangles, 12, nt, in) != nt) die("truncated triangles");
    size_t capacity = 1 << 16, count = 0;
    Batch *all = (Batch *)malloc(capacity * sizeof(Batch));
    for (;;) {
        if (count == capacity) {
            capacity *= 2;
            all = (Batch *)realloc(all, capacity * sizeof(Batch));
        }
        if (!all) die("out of memory");
        size_t got = fread(&all[count], sizeof(Batch), 1, in);
        if (got != 1) break;
        if (all[count].kind > 1) die("bad batch kind");
        count++;
    }
    fclose(in);
    omp_set_num_threads(threads);
    /* EMBREE_PATHRAYS_CONFIG: more of rtcNewDevice's configuration, e.g. verbose=1 (which
     * prints the ISA Embree picked: under valgrind, AVX2). */
    const char *more = getenv("EMBREE_PATHRAYS_CONFIG");
    char config[256];
    snprintf(config, sizeof config, "threads=%d%s%s", threads, more ? "," : "", more ? more : "");
    RTCDevice device = rtcNewDevice(config);
    if (!device) die("rtcNewDevice failed");
    scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, high ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
    if (robust) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    RTCGeometry mesh = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertices, 0, 12, nv);
    rtcSetSharedGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, triangles, 0, 12, nt);
    rtcCommitGeometry(mesh);
    rtcAttachGeometry(scene, mesh);
    rtcReleaseGeometry(mesh);
    rtcCommitScene(scene);
    if (only_kind >= 0) {
        only_group(all, count, only_kind, only_group_, first, repeat);
        return 0;
    }

    const char *kinds[2] = {"closest", "any"};
    const char *steps[3] = {"camera/first", "bounce 1", "bounce 2+"};
    const Batch **set = (const Batch **)malloc(count * sizeof *set);
    char json[16384];
    int len = snprintf(json, sizeof json, "{\"batches\": %zu", count);
    for (int kind = 0; kind < 2; kind++) {
        for (int g = 0; g < 3; g++)
          for (int bucket = 0; bucket < (buckets ? 4 : 1); bucket++) {
            long n = 0, rays = 0;
            for (size_t i = 0; i < count; i++) {
                int step = all[i].step < 2 ? all[i].step : 2;
                int in_bucket = !buckets || (__builtin_popcount(all[i].active) - 1) / 4 == bucket;
                if (all[i].kind == kind && step == g && in_bucket) {
                    set[n++] = &all[i];
                    rays += __builtin_popcount(all[i].active);
                }
            }
            if (!n) continue;
            if (shuffle) { /* Fisher-Yates with a fixed xorshift, as the replay's */
                uint64_t state = 0x9E3779B97F4A7C15ull;
                for (long i = n - 1; i > 0; i--) {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    long j = (long)(state % (uint64_t)(i + 1));
                    const Batch *t = set[i];
                    set[i] = set[j];
                    set[j] = t;
                }
            }
            for (int packets = 1; packets >= 0; packets--) {
                double cpus[100];
                long found = 0;
                for (int run = 0; run < repeat; run++) {
                    double c0 = cpu_now();
                    found = trace(set, n, packets);
                    cpus[run] = cpu_now() - c0;
                }
                qsort(cpus, repeat, sizeof(double), compare);
                double c = cpus[repeat / 2];
                const char *mode = packets ? "packet16" : "single";
                if (buckets) fprintf(stderr, "active %d-%d: ", 4 * bucket + 1, 4 * bucket + 4);
                fprintf(stderr, "%s %s %s: %ld rays, %ld batches, %ld found, %.3f s CPU, %.2f Mrays/CPU-s\n",
                        kinds[kind], steps[g], mode, rays, n, found, c, rays / c * 1e-6);
                len += snprintf(json + len, sizeof json - len, ", \"%s_%d_%d_%s\": %.4f", kinds[kind], g,
                                bucket, mode, rays / c * 1e-6);
            }
        }
    }
    printf("%s}\n", json);
    return 0;
}
