// The SDF of a hash-grid field (trilinear multiresolution hash encoding, then a softplus MLP),
// one point per thread, forward only: the same arithmetic as the CPU engine's
// `HashGrid::encode` and `Mlp::infer` (engine/hashgrid.rs, engine/dense.rs).
//
// The host prepends the field's shape:
//   LEVELS, TABLE (entries per level, a power of two), GRID_OFFSET (first table in params),
//   INPUTS (3 + 2 LEVELS), HIDDEN, HIDDEN_LAYERS, BETA (softplus), and the offsets of each
//   layer's weights (outputs x inputs, row-major) and biases: W0, B0, ..., W{HIDDEN_LAYERS}, B{..}
//   given as the arrays WEIGHT_OFFSETS and BIAS_OFFSETS; each level's RESOLUTIONS (cells per
//   axis) and LEVEL_WEIGHTS (coarse-to-fine annealing, 0 for a level not yet active).

#define FEATURES 2

__constant__ unsigned int resolution[LEVELS] = RESOLUTIONS;
__constant__ float level_weight[LEVELS] = LEVEL_WEIGHTS;

__device__ __forceinline__ float softplus(float x) {
    return fmaxf(x, 0.0f) + log1pf(expf(-fabsf(BETA * x))) / BETA;
}

// Copy the network's weights into shared memory, laid out layer after layer as [weights,
// biases]; of the last layer only the SDF row (the features are not needed here). The host
// sizes it (`network_floats` in mod.rs).
__device__ void load_network(const float* params, float* net) {
    const int weight_offsets[HIDDEN_LAYERS + 1] = WEIGHT_OFFSETS;
    const int bias_offsets[HIDDEN_LAYERS + 1] = BIAS_OFFSETS;
    int at = 0;
    for (int l = 0; l <= HIDDEN_LAYERS; ++l) {
        const int inputs = l == 0 ? INPUTS : HIDDEN;
        const int outputs = l == HIDDEN_LAYERS ? 1 : HIDDEN;
        for (int i = threadIdx.x; i < inputs * outputs; i += blockDim.x) net[at + i] = params[weight_offsets[l] + i];
        at += inputs * outputs;
        for (int i = threadIdx.x; i < outputs; i += blockDim.x) net[at + i] = params[bias_offsets[l] + i];
        at += outputs;
    }
    __syncthreads();
}

// out = softplus(W in + b) for a hidden layer of IN inputs whose weights (HIDDEN x IN, row-major)
// and biases start at w.
template <int IN>
__device__ __forceinline__ void hidden_layer(const float* w, const float* in, float* out) {
#pragma unroll 4
    for (int j = 0; j < HIDDEN; ++j) {
        float acc = w[IN * HIDDEN + j];
#pragma unroll
        for (int i = 0; i < IN; ++i) acc += w[j * IN + i] * in[i];
        out[j] = softplus(acc);
    }
}

__device__ float field_sdf(const float* params, const float* net, float px, float py, float pz) {
    float x[INPUTS];
    x[0] = px;
    x[1] = py;
    x[2] = pz;
    const float p[3] = {px, py, pz};
#pragma unroll
    for (int level = 0; level < LEVELS; ++level) {
        const float lw = level_weight[level];
        float f0 = 0.0f, f1 = 0.0f;
        if (lw != 0.0f) {
            const unsigned int res = resolution[level];
            const unsigned int side = res + 1;
            const bool dense = (unsigned long long)side * side * side <= TABLE;
            unsigned int cell[3];
            float frac[3];
            for (int a = 0; a < 3; ++a) {
                const float u = __fmul_rn(fminf(fmaxf(__fmul_rn(__fadd_rn(p[a], 1.0f), 0.5f), 0.0f), 1.0f), (float)res);
                const unsigned int c = min((unsigned int)u, res - 1);
                cell[a] = c;
                frac[a] = u - (float)c;
            }
            const float* table = params + GRID_OFFSET + (size_t)level * TABLE * FEATURES;
#pragma unroll
            for (int k = 0; k < 8; ++k) {
                const unsigned int c0 = cell[0] + (k & 1), c1 = cell[1] + ((k >> 1) & 1), c2 = cell[2] + ((k >> 2) & 1);
                const float w = ((k & 1) ? frac[0] : 1.0f - frac[0]) * (((k >> 1) & 1) ? frac[1] : 1.0f - frac[1]) *
                                (((k >> 2) & 1) ? frac[2] : 1.0f - frac[2]);
                const unsigned int slot = dense ? c0 + side * (c1 + side * c2)
                                                : (c0 ^ (c1 * 2654435761u) ^ (c2 * 805459861u)) & (TABLE - 1);
                const float2 e = *reinterpret_cast<const float2*>(table + (size_t)slot * FEATURES);
                f0 += w * e.x;
                f1 += w * e.y;
            }
        }
        x[3 + FEATURES * level] = f0 * lw;
        x[4 + FEATURES * level] = f1 * lw;
    }
    float h[HIDDEN], g[HIDDEN];
    hidden_layer<INPUTS>(net, x, h);
    const float* w = net + INPUTS * HIDDEN + HIDDEN;
#pragma unroll
    for (int l = 1; l < HIDDEN_LAYERS; ++l) {
        hidden_layer<HIDDEN>(w, h, g);
#pragma unroll
        for (int j = 0; j < HIDDEN; ++j) h[j] = g[j];
        w += HIDDEN * HIDDEN + HIDDEN;
    }
    float sdf = w[HIDDEN];
#pragma unroll
    for (int i = 0; i < HIDDEN; ++i) sdf += w[i] * h[i];
    return sdf;
}

// The SDF at `n` points (n x 3).
extern "C" __global__ void sdf_points(const float* params, const float* points, float* out, int n) {
    extern __shared__ float net[];
    load_network(params, net);
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    out[i] = field_sdf(params, net, points[3 * i], points[3 * i + 1], points[3 * i + 2]);
}

// The SDF on the (cells + 1)^3 grid over [-1, 1]^3, x fastest; +1 outside the unit sphere.
extern "C" __global__ void sdf_grid(const float* params, float* out, int cells) {
    extern __shared__ float net[];
    load_network(params, net);
    const long long side = cells + 1;
    const long long g = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (g >= side * side * side) return;
    const int ix = (int)(g % side), iy = (int)(g / side % side), iz = (int)(g / (side * side));
    const float px = __fadd_rn(-1.0f, __fdiv_rn(__fmul_rn(2.0f, (float)ix), (float)cells));
    const float py = __fadd_rn(-1.0f, __fdiv_rn(__fmul_rn(2.0f, (float)iy), (float)cells));
    const float pz = __fadd_rn(-1.0f, __fdiv_rn(__fmul_rn(2.0f, (float)iz), (float)cells));
    const float r2 = __fadd_rn(__fadd_rn(__fmul_rn(px, px), __fmul_rn(py, py)), __fmul_rn(pz, pz));
    out[g] = r2 < 1.0f ? field_sdf(params, net, px, py, pz) : 1.0f;
}
