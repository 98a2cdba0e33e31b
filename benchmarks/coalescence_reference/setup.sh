#!/usr/bin/env bash
# Set up the reference PMBM / PMB filters (García-Fernández et al., GitHub
# Agarciafernandez/MTT, folder "PMBM filter") and their Murty routine
# (kBest2DAssign of the Tracker Component Library, GitHub
# USNavalResearchLaboratory/TrackerComponentLibrary, built as an Octave MEX
# file) for the issue-23 benchmark. Nothing third-party enters the jointtrack
# repository: everything goes to CACHE (default /work/cache).
#
# Where the code comes from. This machine has no GitHub access, so the script
# cannot clone: the two repositories are bare git mirrors brought onto the
# machine by the session's `fetch` tool (github:Agarciafernandez/MTT and
# github:USNavalResearchLaboratory/TrackerComponentLibrary), which leaves them
# at /work/.mirror/<owner>+<name>/repo. Elsewhere, any clone works:
#   git clone --bare https://github.com/Agarciafernandez/MTT
#   git clone --bare https://github.com/USNavalResearchLaboratory/TrackerComponentLibrary
# and pass their git directories as MTT_GIT / TCL_GIT.
#
# Usage:
#   MTT_GIT=/work/.mirror/Agarciafernandez+MTT/repo \
#   TCL_GIT=/work/.mirror/USNavalResearchLaboratory+TrackerComponentLibrary/repo \
#   CACHE=/work/cache bash benchmarks/coalescence_reference/setup.sh [--no-apt]
# Commits used for the issue-23 measurement (HEAD of the mirrors):
#   MTT cc5c6df, TrackerComponentLibrary 1ab8fec (override with MTT_REV / TCL_REV).
set -euo pipefail

MTT_GIT=${MTT_GIT:-/work/.mirror/Agarciafernandez+MTT/repo}
TCL_GIT=${TCL_GIT:-/work/.mirror/USNavalResearchLaboratory+TrackerComponentLibrary/repo}
MTT_REV=${MTT_REV:-HEAD}
TCL_REV=${TCL_REV:-HEAD}
CACHE=${CACHE:-/work/cache}

if [[ "${1:-}" != "--no-apt" ]]; then
  # Debian packages: Octave, its headers and mkoctfile (MEX builds), and the
  # statistics package (their code calls mvnpdf and poissrnd).
  apt-get update
  DEBIAN_FRONTEND=noninteractive apt-get install -y octave liboctave-dev octave-statistics
fi

for g in "$MTT_GIT" "$TCL_GIT"; do
  git --git-dir="$g" rev-parse --verify -q HEAD >/dev/null || { echo "not a git directory: $g" >&2; exit 1; }
done

MTT_DIR="$CACHE/mtt"
TCL_DIR="$CACHE/tcl"
MEX_DIR="$CACHE/mex"
rm -rf "$MTT_DIR" "$TCL_DIR" "$MEX_DIR"
mkdir -p "$MTT_DIR" "$TCL_DIR" "$MEX_DIR/shim"

# Their filter and GOSPA code (GOSPA code is used only to cross-check
# jointtrack's GOSPA on their data; the benchmark scores with jointtrack's).
git --git-dir="$MTT_GIT" archive "$MTT_REV" "PMBM filter" "GOSPA code" | tar -x -C "$MTT_DIR"
echo "MTT $(git --git-dir="$MTT_GIT" rev-parse "$MTT_REV")" > "$CACHE/REVISIONS"

# One Octave incompatibility in their code: Octave 7 refuses A(:,:,idx)=[] on
# a 2-D A (one Poisson component), "invalid dimension in delete_elements".
# Keeping the complement is the same operation.
PRUNE="$MTT_DIR/PMBM filter/PoissonMBMtarget_pruning.m"
sed -i 's/^filter_upd_pruned\.covPois(:,:,index_remove)=\[\];/filter_upd_pruned.covPois=filter_upd_pruned.covPois(:,:,~index_remove); % Octave 7 compat (jointtrack setup.sh): A(:,:,idx)=[] fails on a 2-D A/' "$PRUNE"
grep -q "Octave 7 compat" "$PRUNE" || { echo "patch of $PRUNE did not apply" >&2; exit 1; }

# Their Murty routine: kBest2DAssign (C++ source + MEX wrapper) of the TCL.
git --git-dir="$TCL_GIT" archive "$TCL_REV" \
  "Assignment_Algorithms/k-Best_2D_Assignment" MexValidation.h | tar -x -C "$TCL_DIR"
echo "TCL $(git --git-dir="$TCL_GIT" rev-parse "$TCL_REV")" >> "$CACHE/REVISIONS"

# MexValidation.h includes MATLAB's matrix.h and names a few MATLAB-only
# symbols; this shim supplies them for Octave (see its comment).
cat > "$MEX_DIR/shim/matrix.h" <<'EOF'
/* Octave shim for the Tracker Component Library's MexValidation.h.
   MATLAB declares the mx* API in matrix.h; Octave declares it in mex.h
   (built with -R2018a, the interleaved-complex API, for the typed getters).
   Octave lacks MATLAB's opaque/object class ids and the complex-integer
   getters; MexValidation.h only names them in type switches that the
   kBest2DAssign wrapper never reaches with such data (Octave has no complex
   integer arrays), so they are given distinct ids / a plain data pointer. */
#ifndef JT_OCTAVE_MATRIX_SHIM_H
#define JT_OCTAVE_MATRIX_SHIM_H
#include "mex.h"
#define mxOPAQUE_CLASS ((mxClassID) 1000)
#define mxOBJECT_CLASS ((mxClassID) 1001)
#define JT_COMPLEX_INT_GETTER(NAME, TYPE) \
  static inline TYPE *NAME(const mxArray *p) { return (TYPE *) mxGetData(p); }
JT_COMPLEX_INT_GETTER(mxGetComplexInt8s, mxComplexInt8)
JT_COMPLEX_INT_GETTER(mxGetComplexUint8s, mxComplexUint8)
JT_COMPLEX_INT_GETTER(mxGetComplexInt16s, mxComplexInt16)
JT_COMPLEX_INT_GETTER(mxGetComplexUint16s, mxComplexUint16)
JT_COMPLEX_INT_GETTER(mxGetComplexInt32s, mxComplexInt32)
JT_COMPLEX_INT_GETTER(mxGetComplexUint32s, mxComplexUint32)
JT_COMPLEX_INT_GETTER(mxGetComplexInt64s, mxComplexInt64)
JT_COMPLEX_INT_GETTER(mxGetComplexUint64s, mxComplexUint64)
#endif
EOF

# -R2018a: interleaved complex API (mxGetDoubles etc.); defining
# MX_HAS_INTERLEAVED_COMPLEX by hand instead makes Octave panic at run time.
# -fpermissive: the wrapper passes size_t* where Octave's mwSize* is a signed
# 64-bit type (same width; the dimensions are small and non-negative).
KB="$TCL_DIR/Assignment_Algorithms/k-Best_2D_Assignment"
( cd "$MEX_DIR" && CXXFLAGS="$(mkoctfile -p CXXFLAGS) -fpermissive" mkoctfile --mex -R2018a \
    -I"$MEX_DIR/shim" -I"$TCL_DIR" -I"$KB/Shared_C++_Code" \
    "$KB/kBest2DAssign.cpp" "$KB/Shared_C++_Code/ShortestPathCPP.cpp" -o kBest2DAssign.mex )

# Check the build: the k best costs against brute-force enumeration.
octave-cli --no-window-system --eval "
addpath('$MEX_DIR'); assert(exist('kBest2DAssign') == 3, 'kBest2DAssign is not a MEX file');
rand('seed', 1); maxerr = 0;
for t = 1:300
  nr = randi(4); nc = nr + randi(3) - 1; C = rand(nr, nc); C(rand(nr, nc) < 0.2) = Inf;
  if rand < 0.5, C = C'; end
  [r, c] = size(C); P = perms(1:max(r, c)); P = unique(P(:, 1:min(r, c)), 'rows');
  costs = zeros(size(P, 1), 1);
  for i = 1:size(P, 1)
    if r <= c, costs(i) = sum(C(sub2ind(size(C), 1:r, P(i, :))));
    else, costs(i) = sum(C(sub2ind(size(C), P(i, :), 1:c))); end
  end
  costs = sort(costs(isfinite(costs))); kk = min(5, numel(costs));
  if kk == 0, continue; end
  [~, ~, g] = kBest2DAssign(C, 5);
  assert(numel(g) == kk, 'kBest2DAssign returned %d solutions, brute force %d', numel(g), kk);
  maxerr = max(maxerr, max(abs(g(:) - costs(1:kk))));
end
assert(maxerr < 1e-12, 'kBest2DAssign cost error %g', maxerr);
printf('kBest2DAssign MEX: 300 random problems match brute force (max error %g)\n', maxerr);
" 2>&1 | grep -v "ignoring const execution_exception"

echo
echo "export JT_MTT_DIR=$MTT_DIR"
echo "export JT_KBEST_MEX_DIR=$MEX_DIR"
