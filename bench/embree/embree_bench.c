/*
 * Embree 3 (Debian's libembree-dev) on exactly the rays of `raytracer bench`:
 *
 *   raytracer bench SCENE [camera flags] --dump-rays rays.bin
 *   bench/embree/embree_bench rays.bin [--repeat N] [--threads T]
 *
 * Builds the scene's triangles into an Embree scene (RTC_BUILD_QUALITY_MEDIUM, the
 * default; all of Embree's TBB threads, limited to T), then traces, on T OpenMP
 * threads, the primary rays (closest hit), the shadow rays (any hit), the
 * incoherent bounce rays (closest hit) and the same bounce rays as occlusion queries
 * with no limit (any hit, as ambient occlusion's rays), one ray at a time (rtcIntersect1 /
 * rtcOccluded1), for primary and shadow rays also in the 4x4-tile packets the file
 * groups them in (rtcIntersect16 / rtcOccluded16 with a valid mask), and every kind
 * also as arrays of 256 rays through the stream calls (rtcIntersect1M /
 * rtcOccluded1M, coherent for primary and shadow rays). Prints one JSON
 * object of medians: wall and CPU milliseconds and Mrays/s, with hit counts to check
 * that both tracers did the same work.
 *
 * The file (written by `RayWorkload::dump` in src/benchmark.rs), little-endian:
 *   "RTBENCH1"
 *   u32 vertex count,   f32 x, y, z per vertex
 *   u32 triangle count, u32 a, b, c per triangle
 *   u32 n, n primary rays (f32 ox, oy, oz, dx, dy, dz, tmax), tile by tile
 *   u32 m, m primary packets (u32 first, count)
 *   u32 n, n shadow rays, by tile and light
 *   u32 m, m shadow packets (u32 first, count)
 *   u32 n, n incoherent rays
 *
 * Instanced scenes (issue 39's field of dragons, bench/instancing/make_field.py):
 *
 *   bench/embree/embree_bench rays.bin --mesh MESH.bin --instances FIELD.npy
 *
 * builds the rays file's own triangles (the floor) as one geometry of the scene, and
 * the mesh once as a scene of its own, placed by one RTC_GEOMETRY_TYPE_INSTANCE
 * geometry per matrix of FIELD.npy (an (N, 4, 4) float32 array of row-major
 * world-from-object matrices, as `[[instances]]` reads it). Its build time is the
 * commit of both scenes. MESH.bin (bench/embree/write_mesh.py), little-endian:
 *   "RTMESH01", u32 vertex count, f32 x, y, z per vertex, u32 triangle count,
 *   u32 a, b, c per triangle
 *
 * Build: cc -O3 -march=native -fopenmp embree_bench.c -lembree3 -o embree_bench
 * (bench/embree/build.sh).
 *
 * `--only primary|shadow|incoherent|occlusion` traces that kind's single rays once
 * and prints their count and hits, for a build of Embree with its statistics
 * counters (bench/embree/count.sh), which prints them as the process ends.
 */
#include <embree3/rtcore.h>
#include <math.h>
#include <omp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct {
    float o[3], d[3], tmax;
} Ray;

typedef struct {
    uint32_t first, count;
} Packet;

static void die(const char *message) {
    fprintf(stderr, "embree_bench: error: %s\n", message);
    exit(2);
}

static FILE *input;

static void read_exact(void *to, size_t bytes) {
    if (fread(to, 1, bytes, input) != bytes) die("the rays file is truncated");
}

static uint32_t read_u32(void) {
    uint32_t v;
    read_exact(&v, 4);
    return v;
}

static void *read_array(uint32_t count, size_t size, size_t padding) {
    void *data = aligned_alloc(64, ((size_t)count * size + padding + 63) / 64 * 64);
    if (!data) die("out of memory");
    read_exact(data, (size_t)count * size);
    return data;
}

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
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

static double median(double *values, int n) {
    qsort(values, n, sizeof(double), compare);
    return values[n / 2];
}

/* Globals of one run. */
static RTCScene scene;
static uint32_t n_primary, n_primary_packets, n_shadow, n_shadow_packets, n_incoherent;
static Ray *primary, *shadow, *incoherent;
static Packet *primary_packets, *shadow_packets;

static void set_ray(struct RTCRay *r, const Ray *from) {
    r->org_x = from->o[0];
    r->org_y = from->o[1];
    r->org_z = from->o[2];
    r->dir_x = from->d[0];
    r->dir_y = from->d[1];
    r->dir_z = from->d[2];
    r->tnear = 0.0f;
    r->tfar = from->tmax;
    r->time = 0.0f;
    r->mask = 0xFFFFFFFF;
    r->id = 0;
    r->flags = 0;
}

static long closest_single(const Ray *rays, uint32_t n) {
    long hits = 0;
#pragma omp parallel for schedule(dynamic, 1024) reduction(+ : hits)
    for (long i = 0; i < (long)n; i++) {
        struct RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        struct RTCRayHit rh;
        set_ray(&rh.ray, &rays[i]);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &context, &rh);
        hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
    return hits;
}

static long occluded_single(const Ray *rays, uint32_t n) {
    long blocked = 0;
#pragma omp parallel for schedule(dynamic, 1024) reduction(+ : blocked)
    for (long i = 0; i < (long)n; i++) {
        struct RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        struct RTCRay r;
        set_ray(&r, &rays[i]);
        rtcOccluded1(scene, &context, &r);
        blocked += r.tfar < 0.0f; /* set to -inf when blocked */
    }
    return blocked;
}

/* Rays per rtcIntersect1M / rtcOccluded1M call, as `raytracer bench`'s array
 * queries take them. */
#define STREAM 256

static long closest_stream(const Ray *rays, uint32_t n, enum RTCIntersectContextFlags flags) {
    long hits = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : hits)
    for (long first = 0; first < (long)n; first += STREAM) {
        struct RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        context.flags = flags;
        RTC_ALIGN(64) struct RTCRayHit rh[STREAM];
        unsigned m = (unsigned)((long)n - first < STREAM ? (long)n - first : STREAM);
        for (unsigned i = 0; i < m; i++) {
            set_ray(&rh[i].ray, &rays[first + i]);
            rh[i].hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh[i].hit.primID = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect1M(scene, &context, rh, m, sizeof(struct RTCRayHit));
        for (unsigned i = 0; i < m; i++) hits += rh[i].hit.geomID != RTC_INVALID_GEOMETRY_ID;
    }
    return hits;
}

static long occluded_stream(const Ray *rays, uint32_t n, enum RTCIntersectContextFlags flags) {
    long blocked = 0;
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : blocked)
    for (long first = 0; first < (long)n; first += STREAM) {
        struct RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        context.flags = flags;
        RTC_ALIGN(64) struct RTCRay r[STREAM];
        unsigned m = (unsigned)((long)n - first < STREAM ? (long)n - first : STREAM);
        for (unsigned i = 0; i < m; i++) set_ray(&r[i], &rays[first + i]);
        rtcOccluded1M(scene, &context, r, m, sizeof(struct RTCRay));
        for (unsigned i = 0; i < m; i++) blocked += r[i].tfar < 0.0f;
    }
    return blocked;
}

static void set_ray16(struct RTCRay16 *r, int lane, const Ray *from) {
    r->org_x[lane] = from->o[0];
    r->org_y[lane] = from->o[1];
    r->org_z[lane] = from->o[2];
    r->dir_x[lane] = from->d[0];
    r->dir_y[lane] = from->d[1];
    r->dir_z[lane] = from->d[2];
    r->tnear[lane] = 0.0f;
    r->tfar[lane] = from->tmax;
    r->time[lane] = 0.0f;
    r->mask[lane] = 0xFFFFFFFF;
    r->id[lane] = lane;
    r->flags[lane] = 0;
}

static long closest_packets(const Ray *rays, const Packet *packets, uint32_t m) {
    long hits = 0;
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : hits)
    for (long p = 0; p < (long)m; p++) {
        struct RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        RTC_ALIGN(64) struct RTCRayHit16 rh;
        RTC_ALIGN(64) int valid[16];
        for (int lane = 0; lane < 16; lane++) {
            int used = lane < (int)packets[p].count;
            valid[lane] = used ? -1 : 0;
            set_ray16(&rh.ray, lane, &rays[packets[p].first + (used ? lane : 0)]);
            rh.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, scene, &context, &rh);
        for (int lane = 0; lane < (int)packets[p].count; lane++)
            hits += rh.hit.geomID[lane] != RTC_INVALID_GEOMETRY_ID;
    }
    return hits;
}

static long occluded_packets(const Ray *rays, const Packet *packets, uint32_t m) {
    long blocked = 0;
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : blocked)
    for (long p = 0; p < (long)m; p++) {
        struct RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        RTC_ALIGN(64) struct RTCRay16 r;
        RTC_ALIGN(64) int valid[16];
        for (int lane = 0; lane < 16; lane++) {
            int used = lane < (int)packets[p].count;
            valid[lane] = used ? -1 : 0;
            set_ray16(&r, lane, &rays[packets[p].first + (used ? lane : 0)]);
        }
        rtcOccluded16(valid, scene, &context, &r);
        for (int lane = 0; lane < (int)packets[p].count; lane++) blocked += r.tfar[lane] < 0.0f;
    }
    return blocked;
}

/* The instanced mode's inputs (NULL without --mesh). */
static float *mesh_vertices, *matrices;
static uint32_t *mesh_triangles;
static uint32_t n_mesh_vertices, n_mesh_triangles, n_instances;

/* Reads MESH.bin into the mesh arrays. */
static void read_mesh(const char *path) {
    input = fopen(path, "rb");
    if (!input) die("cannot open the --mesh file");
    char magic[8];
    read_exact(magic, 8);
    if (memcmp(magic, "RTMESH01", 8)) die("--mesh: not a file of bench/embree/write_mesh.py");
    n_mesh_vertices = read_u32();
    mesh_vertices = read_array(n_mesh_vertices, 12, 16);
    n_mesh_triangles = read_u32();
    mesh_triangles = read_array(n_mesh_triangles, 12, 0);
    fclose(input);
}

/* Reads an (N, 4, 4) little-endian float32 .npy file (version 1 or 2 header) into
 * `matrices`: N row-major 4x4 matrices. */
static void read_npy(const char *path) {
    input = fopen(path, "rb");
    if (!input) die("cannot open the --instances file");
    unsigned char head[10];
    read_exact(head, 10);
    if (memcmp(head, "\x93NUMPY", 6)) die("--instances: not a .npy file");
    uint32_t header_len;
    if (head[6] == 1) {
        header_len = head[8] | (uint32_t)head[9] << 8;
    } else {
        unsigned char more[2];
        read_exact(more, 2);
        header_len = head[8] | (uint32_t)head[9] << 8 | (uint32_t)more[0] << 16 |
                     (uint32_t)more[1] << 24;
    }
    if (header_len > 65536) die("--instances: header too long");
    char header[65537];
    read_exact(header, header_len);
    header[header_len] = 0;
    if (!strstr(header, "'<f4'") || strstr(header, "'fortran_order': True"))
        die("--instances: needs little-endian float32 in C order");
    const char *shape = strstr(header, "'shape': (");
    unsigned long n;
    if (!shape || sscanf(shape, "'shape': (%lu, 4, 4)", &n) != 1 || n == 0 || n > 100000000)
        die("--instances: needs shape (N, 4, 4)");
    n_instances = (uint32_t)n;
    matrices = read_array(n_instances, 64, 0);
    fclose(input);
}

/* The scene of an instanced run: the floor's triangles (`vertices`, `triangles`) as
 * one geometry, and each matrix placing the mesh's own scene (`*mesh_scene`, made
 * here and released by the caller). Not committed. */
static RTCScene new_instanced_scene(RTCDevice device, float *vertices, uint32_t n_vertices,
                                    uint32_t *triangles, uint32_t n_triangles,
                                    RTCScene *mesh_scene) {
    RTCScene top = rtcNewScene(device);
    rtcSetSceneBuildQuality(top, RTC_BUILD_QUALITY_MEDIUM);
    if (n_triangles > 0) {
        RTCGeometry floor = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
        rtcSetSharedGeometryBuffer(floor, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertices, 0,
                                   12, n_vertices);
        rtcSetSharedGeometryBuffer(floor, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, triangles, 0,
                                   12, n_triangles);
        rtcCommitGeometry(floor);
        rtcAttachGeometry(top, floor);
        rtcReleaseGeometry(floor);
    }
    *mesh_scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(*mesh_scene, RTC_BUILD_QUALITY_MEDIUM);
    RTCGeometry mesh = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, mesh_vertices, 0,
                               12, n_mesh_vertices);
    rtcSetSharedGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh_triangles, 0,
                               12, n_mesh_triangles);
    rtcCommitGeometry(mesh);
    rtcAttachGeometry(*mesh_scene, mesh);
    rtcReleaseGeometry(mesh);
    for (uint32_t i = 0; i < n_instances; i++) {
        RTCGeometry instance = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(instance, *mesh_scene);
        /* The first three rows of the row-major 4x4 matrix. */
        rtcSetGeometryTransform(instance, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, &matrices[16 * i]);
        rtcCommitGeometry(instance);
        rtcAttachGeometry(top, instance);
        rtcReleaseGeometry(instance);
    }
    return top;
}

#define MAX_REPEAT 100

/* Times `call` `repeat` times: medians of wall and CPU seconds into `wall`, `cpu`. */
#define TIME(repeat, result, wall, cpu, call)                                  \
    do {                                                                       \
        double walls[MAX_REPEAT], cpus[MAX_REPEAT];                            \
        for (int run = 0; run < (repeat); run++) {                             \
            double w0 = now(), c0 = cpu_now();                                 \
            result = (call);                                                   \
            walls[run] = now() - w0;                                           \
            cpus[run] = cpu_now() - c0;                                        \
        }                                                                      \
        wall = median(walls, repeat);                                          \
        cpu = median(cpus, repeat);                                            \
    } while (0)

static void print_rate(const char *name, uint32_t n, double wall, double cpu) {
    printf(", \"%s_ms\": %.2f, \"%s_cpu_ms\": %.2f, \"%s_mrays_per_s\": %.2f, "
           "\"%s_mrays_per_cpu_s\": %.2f",
           name, wall * 1e3, name, cpu * 1e3, name, n / wall / 1e6, name, n / cpu / 1e6);
}

int main(int argc, char **argv) {
    const char *path = NULL, *mesh_path = NULL, *instances_path = NULL, *only = NULL;
    int repeat = 5, threads = 2;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--repeat") && i + 1 < argc)
            repeat = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--mesh") && i + 1 < argc)
            mesh_path = argv[++i];
        else if (!strcmp(argv[i], "--instances") && i + 1 < argc)
            instances_path = argv[++i];
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc)
            threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--only") && i + 1 < argc)
            only = argv[++i];
        else if (argv[i][0] != '-' && !path)
            path = argv[i];
        else
            die("usage: embree_bench RAYS.bin [--repeat N] [--threads T] [--mesh M --instances I]");
    }
    if (!path) die("usage: embree_bench RAYS.bin [--repeat N] [--threads T] [--mesh M --instances I]");
    if (!mesh_path != !instances_path) die("--mesh and --instances go together");
    if (repeat < 1 || repeat > MAX_REPEAT) die("--repeat takes 1 to 100");
    if (threads < 1) die("--threads takes a positive number");
    input = fopen(path, "rb");
    if (!input) die("cannot open the rays file");
    char magic[8];
    read_exact(magic, 8);
    if (memcmp(magic, "RTBENCH1", 8)) die("not a rays file of raytracer bench --dump-rays");
    uint32_t n_vertices = read_u32();
    /* Embree reads vertex buffers 16 bytes at a time: pad the last vertex. */
    float *vertices = read_array(n_vertices, 12, 16);
    uint32_t n_triangles = read_u32();
    uint32_t *triangles = read_array(n_triangles, 12, 0);
    n_primary = read_u32();
    primary = read_array(n_primary, sizeof(Ray), 0);
    n_primary_packets = read_u32();
    primary_packets = read_array(n_primary_packets, sizeof(Packet), 0);
    n_shadow = read_u32();
    shadow = read_array(n_shadow, sizeof(Ray), 0);
    n_shadow_packets = read_u32();
    shadow_packets = read_array(n_shadow_packets, sizeof(Packet), 0);
    n_incoherent = read_u32();
    incoherent = read_array(n_incoherent, sizeof(Ray), 0);
    fclose(input);
    if (mesh_path) {
        read_mesh(mesh_path);
        read_npy(instances_path);
    }
    omp_set_num_threads(threads);

    char config[64];
    snprintf(config, sizeof config, "threads=%d", threads);
    RTCDevice device = rtcNewDevice(config);
    if (!device) die("rtcNewDevice failed");
    long ray16 = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED);

    /* Build: a new scene each time; only the commit is timed. */
    double builds[MAX_REPEAT], build_cpus[MAX_REPEAT];
    RTCScene mesh_scene = NULL;
    for (int run = 0; run < repeat; run++) {
        if (scene) rtcReleaseScene(scene);
        if (mesh_scene) rtcReleaseScene(mesh_scene);
        if (mesh_path) {
            scene = new_instanced_scene(device, vertices, n_vertices, triangles, n_triangles,
                                        &mesh_scene);
            double w0 = now(), c0 = cpu_now();
            rtcCommitScene(mesh_scene);
            rtcCommitScene(scene);
            builds[run] = now() - w0;
            build_cpus[run] = cpu_now() - c0;
            continue;
        }
        scene = rtcNewScene(device);
        rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
        RTCGeometry mesh = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
        rtcSetSharedGeometryBuffer(mesh, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertices, 0,
                                   12, n_vertices);
        rtcSetSharedGeometryBuffer(mesh, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, triangles, 0,
                                   12, n_triangles);
        rtcCommitGeometry(mesh);
        rtcAttachGeometry(scene, mesh);
        rtcReleaseGeometry(mesh);
        double w0 = now(), c0 = cpu_now();
        rtcCommitScene(scene);
        builds[run] = now() - w0;
        build_cpus[run] = cpu_now() - c0;
    }
    double build = median(builds, repeat), build_cpu = median(build_cpus, repeat);

    if (only) {
        long found = -1;
        uint32_t n = 0;
        if (!strcmp(only, "primary")) {
            n = n_primary;
            found = closest_single(primary, n);
        } else if (!strcmp(only, "shadow")) {
            n = n_shadow;
            found = occluded_single(shadow, n);
        } else if (!strcmp(only, "incoherent")) {
            n = n_incoherent;
            found = closest_single(incoherent, n);
        } else if (!strcmp(only, "occlusion")) {
            n = n_incoherent;
            found = occluded_single(incoherent, n);
        } else {
            die("--only takes primary, shadow, incoherent or occlusion");
        }
        printf("{\"only\": \"%s\", \"rays\": %u, \"hits_or_blocked\": %ld}\n", only, n, found);
        fflush(stdout);
        rtcReleaseScene(scene);
        if (mesh_scene) rtcReleaseScene(mesh_scene);
        rtcReleaseDevice(device);
        return 0;
    }
    long primary_hits, primary_packet_hits, occluded, packet_occluded, incoherent_hits,
        occlusion_blocked;
    double w, c;
    printf("{\"peer\": \"embree\", \"version\": \"Embree %d.%d.%d (libembree-dev)\", "
           "\"native_ray16\": %ld, \"threads\": %d, \"triangles\": %u",
           RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH, ray16, threads, n_triangles);
    if (mesh_path)
        printf(", \"instances\": %u, \"mesh_triangles\": %u", n_instances, n_mesh_triangles);
    printf(", \"build_ms\": %.2f, \"build_cpu_ms\": %.2f", build * 1e3, build_cpu * 1e3);
    TIME(repeat, primary_hits, w, c, closest_single(primary, n_primary));
    printf(", \"primary_rays\": %u, \"primary_hits\": %ld", n_primary, primary_hits);
    print_rate("primary", n_primary, w, c);
    TIME(repeat, primary_packet_hits, w, c,
         closest_packets(primary, primary_packets, n_primary_packets));
    printf(", \"primary_packet_hits\": %ld", primary_packet_hits);
    print_rate("primary_packet", n_primary, w, c);
    TIME(repeat, occluded, w, c, occluded_single(shadow, n_shadow));
    printf(", \"shadow_rays\": %u, \"shadow_occluded\": %ld", n_shadow, occluded);
    print_rate("shadow", n_shadow, w, c);
    TIME(repeat, packet_occluded, w, c, occluded_packets(shadow, shadow_packets, n_shadow_packets));
    printf(", \"shadow_packet_occluded\": %ld", packet_occluded);
    print_rate("shadow_packet", n_shadow, w, c);
    TIME(repeat, incoherent_hits, w, c, closest_single(incoherent, n_incoherent));
    printf(", \"incoherent_rays\": %u, \"incoherent_hits\": %ld", n_incoherent, incoherent_hits);
    print_rate("incoherent", n_incoherent, w, c);
    TIME(repeat, occlusion_blocked, w, c, occluded_single(incoherent, n_incoherent));
    printf(", \"occlusion_rays\": %u, \"occlusion_blocked\": %ld", n_incoherent,
           occlusion_blocked);
    print_rate("occlusion", n_incoherent, w, c);
    /* The same arrays through Embree's stream calls, 256 rays a call: coherent for
     * the camera and shadow rays (tile by tile), incoherent for the bounces. */
    long stream_hits;
    TIME(repeat, stream_hits, w, c,
         closest_stream(primary, n_primary, RTC_INTERSECT_CONTEXT_FLAG_COHERENT));
    printf(", \"primary_stream_hits\": %ld", stream_hits);
    print_rate("primary_stream", n_primary, w, c);
    TIME(repeat, stream_hits, w, c,
         occluded_stream(shadow, n_shadow, RTC_INTERSECT_CONTEXT_FLAG_COHERENT));
    printf(", \"shadow_stream_occluded\": %ld", stream_hits);
    print_rate("shadow_stream", n_shadow, w, c);
    TIME(repeat, stream_hits, w, c,
         closest_stream(incoherent, n_incoherent, RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT));
    printf(", \"incoherent_stream_hits\": %ld", stream_hits);
    print_rate("incoherent_stream", n_incoherent, w, c);
    TIME(repeat, stream_hits, w, c,
         occluded_stream(incoherent, n_incoherent, RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT));
    printf(", \"occlusion_stream_blocked\": %ld", stream_hits);
    print_rate("occlusion_stream", n_incoherent, w, c);
    printf("}\n");
    rtcReleaseScene(scene);
    if (mesh_scene) rtcReleaseScene(mesh_scene);
    rtcReleaseDevice(device);
    return 0;
}
