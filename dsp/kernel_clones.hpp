// Hot loops get an AVX2 + FMA clone picked at load time where the CPU has it (x86-64 only), and stay portable
// elsewhere. Not under ThreadSanitizer: the clone's resolver runs while the program is relocated, before
// TSan's runtime is up, and its instrumented code crashes there.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(NOISEMON_SANITIZE_THREAD)
#define NOISEMON_KERNEL_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define NOISEMON_KERNEL_CLONES
#endif
// Helpers of a cloned kernel are forced inline so that they are compiled for the clone that calls them.
#define NOISEMON_INLINE inline __attribute__((always_inline))
