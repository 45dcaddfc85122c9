// Reads and writes DualSPHysics' particle files (.bi4) for experiments/dualsphysics.py.
//
// DualSPHysics' pre-processor GenCase is published as a binary only, so the experiment
// lays the particles out itself (our dam-break builder's lattice, the same particles on
// both sides) and this tool stores them in the case file the solver loads, with the
// solver's own writer (JPartDataBi4, compiled from the DualSPHysics source tree given to
// the compiler). It also reads the solver's output parts back as text.
//
//   fpsi_dsph_io case <dir> <casename> <particles.txt>
//       particles.txt: line 1 "np nfixed nfluid dp h b rhop0 gamma massbound massfluid";
//       then np lines "x z vx vz rho", the fixed boundary first, then the fluid.
//       Writes <dir>/<casename>.bi4 (2D, y = 0).
//   fpsi_dsph_io dump <Part_xxxx.bi4> <out.txt>
//       out.txt: line 1 "time npok", then npok lines "idp x z vx vz rho".
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>
#include "JPartDataBi4.h"
#include "Functions.h"

static int write_case(const std::string& dir, const std::string& name, const char* path) {
  FILE* f = std::fopen(path, "r");
  if (!f) { std::fprintf(stderr, "cannot open %s\n", path); return 1; }
  unsigned long long np, nfixed, nfluid;
  double dp, h, b, rho0, gamma, mb, mf;
  if (std::fscanf(f, "%llu %llu %llu %lf %lf %lf %lf %lf %lf %lf", &np, &nfixed, &nfluid,
                  &dp, &h, &b, &rho0, &gamma, &mb, &mf) != 10 || np != nfixed + nfluid) {
    std::fprintf(stderr, "bad header in %s\n", path); return 1;
  }
  std::vector<unsigned> idp(np);
  std::vector<tdouble3> pos(np);
  std::vector<tfloat3> vel(np);
  std::vector<float> rho(np);
  tdouble3 lo = TDouble3(1e30), hi = TDouble3(-1e30);
  for (unsigned long long i = 0; i < np; i++) {
    double x, z, vx, vz, r;
    if (std::fscanf(f, "%lf %lf %lf %lf %lf", &x, &z, &vx, &vz, &r) != 5) {
      std::fprintf(stderr, "particle %llu unreadable in %s\n", i, path); return 1;
    }
    idp[i] = unsigned(i);
    pos[i] = TDouble3(x, 0, z);
    vel[i] = TFloat3(float(vx), 0, float(vz));
    rho[i] = float(r);
    lo = MinValues(lo, pos[i]);
    hi = MaxValues(hi, pos[i]);
  }
  std::fclose(f);
  JPartDataBi4 pd;
  pd.ConfigBasic(0, 1, "", "fpsi_dsph_io", name, true, 0.0, dir);
  pd.ConfigParticles(np, nfixed, 0, 0, nfluid, lo, hi);
  pd.ConfigCtes(dp, h, b, rho0, gamma, mb, mf);
  pd.ConfigSimMap(TDouble3(0), TDouble3(0));  // equal: the solver sizes the domain itself
  pd.AddPartInfo(0, 0, unsigned(np), 0, 0, 0, lo, hi);
  pd.AddPartData(unsigned(np), idp.data(), pos.data(), vel.data(), rho.data());
  pd.SaveFileCase(name);
  return 0;
}

static int dump(const char* file, const char* out) {
  JPartDataBi4 pd;
  pd.LoadFilename(file);
  const unsigned n = pd.Get_Npok();
  std::vector<unsigned> idp(n);
  std::vector<tfloat3> vel(n);
  std::vector<float> rho(n);
  std::vector<tdouble3> pos(n);
  pd.Get_Idp(n, idp.data());
  if (pd.Get_PosSimple()) {
    std::vector<tfloat3> p(n);
    pd.Get_Pos(n, p.data());
    for (unsigned i = 0; i < n; i++) pos[i] = ToTDouble3(p[i]);
  } else {
    pd.Get_Posd(n, pos.data());
  }
  pd.Get_Vel(n, vel.data());
  pd.Get_Rhop(n, rho.data());
  FILE* f = std::fopen(out, "w");
  if (!f) { std::fprintf(stderr, "cannot write %s\n", out); return 1; }
  std::fprintf(f, "%.9g %u\n", pd.Get_TimeStep(), n);
  for (unsigned i = 0; i < n; i++)
    std::fprintf(f, "%u %.9g %.9g %.7g %.7g %.7g\n", idp[i], pos[i].x, pos[i].z, vel[i].x,
                 vel[i].z, rho[i]);
  std::fclose(f);
  return 0;
}

int main(int argc, char** argv) {
  try {
    std::string cmd = argc > 1 ? argv[1] : "";
    if (cmd == "case" && argc == 5) return write_case(argv[2], argv[3], argv[4]);
    if (cmd == "dump" && argc == 4) return dump(argv[2], argv[3]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  std::fprintf(stderr, "usage: fpsi_dsph_io case <dir> <casename> <particles.txt> | "
                       "dump <part.bi4> <out.txt>\n");
  return 2;
}
