// The CUDA names ao.cu uses, for its HOST_EMULATION build on a machine without CUDA:
//   sed 's/<<<grid, block>>>//' ao.cu > /tmp/t.cpp && g++ -O2 -std=c++17 -DHOST_EMULATION \
//     -include cstring -include cstdint -include cstdlib -Ihost_shim /tmp/t.cpp -o /tmp/emu
//   /tmp/emu <dump_ao dir with DUMP_REF=1> 1   (then every pixel against the CPU's AO)
#pragma once
#include <cmath>
#define __device__
#define __global__
#define __host__
#define __forceinline__ inline
#define __shared__ static
#define __restrict__
#define __launch_bounds__(x)
struct uint4 { unsigned x,y,z,w; };
struct uint2 { unsigned x,y; };
inline uint2 make_uint2(unsigned a, unsigned b){ return {a,b}; }
struct dim3 { unsigned x,y,z; dim3(unsigned a=1,unsigned b=1,unsigned c=1):x(a),y(b),z(c){} };
static dim3 threadIdx, blockIdx;
typedef int cudaError_t; typedef void* cudaEvent_t;
enum { cudaSuccess=0, cudaMemcpyHostToDevice, cudaMemcpyDeviceToHost };
inline const char* cudaGetErrorString(int){return "";}
template<class T> int cudaMalloc(T**p, size_t n){*p=(T*)calloc(1,n); return 0;}
inline int cudaMemcpy(void*d, const void*s, size_t n, int){memcpy(d,s,n);return 0;}
inline int cudaMemset(void*d, int v, size_t n){memset(d,v,n);return 0;}
inline int cudaDeviceSynchronize(){return 0;}
inline int cudaEventCreate(cudaEvent_t*){return 0;}
inline int cudaEventRecord(cudaEvent_t){return 0;}
inline int cudaEventSynchronize(cudaEvent_t){return 0;}
inline int cudaEventElapsedTime(float*, cudaEvent_t, cudaEvent_t){return 0;}
inline float __uint_as_float(unsigned u){float f; memcpy(&f,&u,4); return f;}
inline unsigned __float_as_uint(float f){unsigned u; memcpy(&u,&f,4); return u;}
inline int __popc(unsigned x){return __builtin_popcount(x);}
inline int __clz(unsigned x){return __builtin_clz(x);}
inline unsigned __activemask(){return 1;}
inline unsigned __ballot_sync(unsigned, int p){return p;}
inline unsigned atomicAdd(unsigned* a, unsigned v){unsigned o=*a; *a+=v; return o;}
inline unsigned long long atomicAdd(unsigned long long* a, unsigned long long v){auto o=*a; *a+=v; return o;}
inline void __syncthreads(){}
inline float rsqrtf(float x){return 1/sqrtf(x);}
inline void __sincosf(float x, float*s, float*c){*s=sinf(x);*c=cosf(x);}
using std::min;
inline float __fmul_rn(float a, float b){ volatile float r = a*b; return r; }
inline float __fsub_rn(float a, float b){ volatile float r = a-b; return r; }
#define __constant__ static
template<class T> int cudaMemcpyToSymbol(T& s, const void* p, size_t n){ memcpy(&s,p,n); return 0;}
