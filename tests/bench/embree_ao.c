// The CPU backend's anchor: Embree's throughput on the AO workload `runner bench
// --backend cpu --integrator ao` times, on the same OBJ (what `runner generate` writes:
// `v` and `f` lines, a `# camera:` comment). One camera ray through each pixel's centre,
// then `ao_rays` cosine-weighted occlusion rays of length `ao_distance` from each hit,
// offset off the surface as our kernels do. Single-ray API (rtcIntersect1/rtcOccluded1),
// as our kernels trace one ray at a time; `threads` worker threads over image rows.
//
// build: cc -O2 -o embree_ao tests/bench/embree_ao.c -lembree3 -lpthread -lm
// usage: embree_ao SCENE.obj WIDTH HEIGHT AO_RAYS AO_DISTANCE THREADS RUNS
// (AO_DISTANCE 0: a quarter of the bounding box's diagonal, `--ao-distance`'s default)
// prints one line per run: rays, seconds, M rays/s, and the image's mean AO.
#include <embree3/rtcore.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct { float x, y, z; } v3;
static v3 add(v3 a, v3 b) { return (v3){a.x + b.x, a.y + b.y, a.z + b.z}; }
static v3 sub(v3 a, v3 b) { return (v3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static v3 mul(v3 a, float s) { return (v3){a.x * s, a.y * s, a.z * s}; }
static float dot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static v3 cross(v3 a, v3 b) {
  return (v3){a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
static v3 norm(v3 a) { return mul(a, 1.0f / sqrtf(dot(a, a))); }

static float *verts;
static unsigned *tris;
static size_t nv, nt, cap_v, cap_t;
static v3 eye, target, up = {0, 1, 0};
static float fov = 45.0f;

static void load_obj(const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) { perror(path); exit(1); }
  char line[4096];
  while (fgets(line, sizeof line, f)) {
    if (line[0] == 'v' && line[1] == ' ') {
      if (nv + 1 > cap_v) { cap_v = cap_v ? 2 * cap_v : 1024; verts = realloc(verts, cap_v * 12); }
      sscanf(line + 2, "%f %f %f", &verts[3 * nv], &verts[3 * nv + 1], &verts[3 * nv + 2]);
      nv++;
    } else if (line[0] == 'f' && line[1] == ' ') {
      // A fan over the face's corners (n-gons), each `i`, `i/t`, `i/t/n` or `i//n`.
      long idx[64];
      int k = 0;
      char *s = line + 2, *end;
      while (k < 64) {
        long i = strtol(s, &end, 10);
        if (end == s) break;
        idx[k++] = i < 0 ? (long)nv + i : i - 1;
        s = end;
        while (*s && *s != ' ' && *s != '\t' && *s != '\n') s++;
      }
      for (int j = 1; j + 1 < k; j++) {
        if (nt + 1 > cap_t) { cap_t = cap_t ? 2 * cap_t : 1024; tris = realloc(tris, cap_t * 12); }
        tris[3 * nt] = idx[0]; tris[3 * nt + 1] = idx[j]; tris[3 * nt + 2] = idx[j + 1];
        nt++;
      }
    } else if (!strncmp(line, "# camera:", 9)) {
      sscanf(line, "# camera: eye=%f,%f,%f target=%f,%f,%f up=%f,%f,%f fov=%f", &eye.x, &eye.y,
             &eye.z, &target.x, &target.y, &target.z, &up.x, &up.y, &up.z, &fov);
    }
  }
  fclose(f);
}

static RTCScene scene;
static int width, height, ao_rays, next_row;
static float ao_distance;
static double *row_ao;
static uint64_t *row_rays;
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;

static uint32_t pcg(uint32_t v) {
  uint32_t s = v * 747796405u + 2891336453u;
  uint32_t w = ((s >> ((s >> 28) + 4)) ^ s) * 277803737u;
  return (w >> 22) ^ w;
}

// Our kernels' `offset_ray_origin` (Wächter & Binder, Ray Tracing Gems ch. 6).
static float offset_component(float p, float n) {
  if (fabsf(p) < 1.0f / 32.0f) return p + n / 65536.0f;
  int32_t of = (int32_t)(256.0f * n), bits;
  memcpy(&bits, &p, 4);
  bits = p < 0 ? bits - of : bits + of;
  memcpy(&p, &bits, 4);
  return p;
}

static void *worker(void *arg) {
  (void)arg;
  v3 w = norm(sub(eye, target)), u = norm(cross(up, w)), v = cross(w, u);
  float half_h = tanf(fov * 0.5f * 3.14159265f / 180.0f), aspect = (float)width / height;
  struct RTCIntersectContext ctx;
  for (;;) {
    pthread_mutex_lock(&lock);
    int y = next_row++;
    pthread_mutex_unlock(&lock);
    if (y >= height) return NULL;
    double sum = 0;
    uint64_t rays = 0;
    for (int x = 0; x < width; x++) {
      float sx = (2.0f * (x + 0.5f) / width - 1.0f) * half_h * aspect;
      float sy = (1.0f - 2.0f * (y + 0.5f) / height) * half_h;
      v3 d = norm(add(add(mul(u, sx), mul(v, sy)), mul(w, -1.0f)));
      struct RTCRayHit rh = {0};
      rh.ray.org_x = eye.x; rh.ray.org_y = eye.y; rh.ray.org_z = eye.z;
      rh.ray.dir_x = d.x; rh.ray.dir_y = d.y; rh.ray.dir_z = d.z;
      rh.ray.tnear = 0; rh.ray.tfar = INFINITY; rh.ray.mask = -1;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcInitIntersectContext(&ctx);
      rtcIntersect1(scene, &ctx, &rh);
      rays++;
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      v3 p = add(eye, mul(d, rh.ray.tfar));
      v3 n = norm((v3){rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z});
      if (dot(n, d) > 0) n = mul(n, -1.0f);
      v3 o = {offset_component(p.x, n.x), offset_component(p.y, n.y), offset_component(p.z, n.z)};
      // Orthonormal basis about n (Duff et al. 2017).
      float sgn = copysignf(1.0f, n.z), a = -1.0f / (sgn + n.z), b = n.x * n.y * a;
      v3 t1 = {1.0f + sgn * n.x * n.x * a, sgn * b, -sgn * n.x}, t2 = {b, sgn + n.y * n.y * a, -n.y};
      int open = 0;
      uint32_t seed = pcg((uint32_t)(y * width + x));
      for (int i = 0; i < ao_rays; i++) {
        float r1 = (pcg(seed ^ (2 * i)) >> 8) * (1.0f / 16777216.0f);
        float r2 = (pcg(seed ^ (2 * i + 1)) >> 8) * (1.0f / 16777216.0f);
        float r = sqrtf(r1), phi = 6.2831853f * r2;
        v3 dir = add(add(mul(t1, r * cosf(phi)), mul(t2, r * sinf(phi))), mul(n, sqrtf(1 - r1)));
        struct RTCRay ray = {0};
        ray.org_x = o.x; ray.org_y = o.y; ray.org_z = o.z;
        ray.dir_x = dir.x; ray.dir_y = dir.y; ray.dir_z = dir.z;
        ray.tnear = 0; ray.tfar = ao_distance; ray.mask = -1;
        rtcInitIntersectContext(&ctx);
        rtcOccluded1(scene, &ctx, &ray);
        open += ray.tfar >= 0;  // Embree sets tfar = -inf on a hit
      }
      rays += ao_rays;
      sum += (double)open / ao_rays;
    }
    row_ao[y] = sum;
    row_rays[y] = rays;
  }
}

int main(int argc, char **argv) {
  if (argc != 8) {
    fprintf(stderr, "usage: %s SCENE.obj WIDTH HEIGHT AO_RAYS AO_DISTANCE THREADS RUNS\n", argv[0]);
    return 2;
  }
  load_obj(argv[1]);
  width = atoi(argv[2]); height = atoi(argv[3]); ao_rays = atoi(argv[4]);
  ao_distance = atof(argv[5]);
  int threads = atoi(argv[6]), runs = atoi(argv[7]);
  if (ao_distance <= 0) {
    v3 lo = {INFINITY, INFINITY, INFINITY}, hi = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < nv; i++) {
      v3 p = {verts[3 * i], verts[3 * i + 1], verts[3 * i + 2]};
      lo = (v3){fminf(lo.x, p.x), fminf(lo.y, p.y), fminf(lo.z, p.z)};
      hi = (v3){fmaxf(hi.x, p.x), fmaxf(hi.y, p.y), fmaxf(hi.z, p.z)};
    }
    v3 d = sub(hi, lo);
    ao_distance = 0.25f * sqrtf(dot(d, d));
  }
  char config[64];
  // Embree's own threads build the BVH; the render uses ours.
  snprintf(config, sizeof config, "threads=%d", threads);
  RTCDevice dev = rtcNewDevice(config);
  scene = rtcNewScene(dev);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, nv);
  memcpy(vb, verts, nv * 12);
  unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, nt);
  memcpy(ib, tris, nt * 12);
  rtcCommitGeometry(g);
  rtcAttachGeometry(scene, g);
  rtcReleaseGeometry(g);
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  rtcCommitScene(scene);
  clock_gettime(CLOCK_MONOTONIC, &t1);
  fprintf(stderr, "%zu triangles, BVH build %.2f s\n", nt,
          (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec));
  row_ao = calloc(height, sizeof *row_ao);
  row_rays = calloc(height, sizeof *row_rays);
  for (int run = 0; run < runs; run++) {
    next_row = 0;
    pthread_t th[256];
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (int i = 0; i < threads; i++) pthread_create(&th[i], NULL, worker, NULL);
    for (int i = 0; i < threads; i++) pthread_join(th[i], NULL);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double s = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec), ao = 0;
    uint64_t rays = 0;
    for (int y = 0; y < height; y++) { ao += row_ao[y]; rays += row_rays[y]; }
    printf("rays %llu  %.3f s  %.2f M rays/s  mean AO %.4f\n", (unsigned long long)rays, s,
           rays / s * 1e-6, ao / ((double)width * height));
  }
  return 0;
}
