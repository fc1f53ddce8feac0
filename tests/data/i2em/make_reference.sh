#!/usr/bin/env bash
# Reference sigma nought from the public MATLAB code of Ulaby and Long, "Microwave Radar and
# Radiometric Remote Sensing" (2014), codes 10.1 and 10.3 (I2EM_Bistat_model.m, IEMX_model.m),
# run under GNU Octave. The code is not part of this repository; a public copy is in the history
# of github.com/Morteza-Khazaei/mwrtms (commit c70b91a, folder .temp/MATLAB/mrs.eecs.umich.edu/).
#
# Usage: tests/data/i2em/make_reference.sh BOOK_CODE_DIR [KIND]
#   reads cases_KIND.csv beside this script and writes reference_KIND.csv there (columns: the case's,
#   then the code's sigma nought in dB). A KIND starting with "copol" runs the co-polarised code
#   (I2EM_Bistat_model), any other the cross-polarised one (IEMX_model). The kinds:
#     copol          816 monostatic and bistatic cases (k s 0.1 to 2.5, k l 2 to 8);
#     cross          12 HV cases, s / l <= 0.24, incidence <= 50 deg;
#     cross_shadow   12 HV cases where Smith's shadowing counts: s / l 0.25 to 0.5, incidence 60 to
#                    80 deg (the single-scattering shadowing 0.2 to 3.4 dB);
#     copol_tables, cross_tables (22 and 3 cases)
#                    the angles of nodes of sarmitsuba/scene/rough_tables.py's tables, for two
#                    surfaces: monostatic cos = i / 256 (i = 0 at cos = 0.01), bistatic cos_i = a / 32,
#                    cos_s = b / 32, cos phi_s = -1 + m / 8.
#
# Two adaptations, both to Octave's dblquad (the numbers are the book code's own):
#   1. Octave's dblquad wants a real integrand: the slope-averaged reflection coefficients of
#      I2EM_Bistat_model are integrated as real and imaginary parts apart (cdblquad below);
#   2. Octave passes the inner variable as a column, MATLAB as a row: IEMX_model's integrand is
#      called on r(:).' and its value reshaped to r's shape.
# and one to the geometry, unless GUARD=kept:
#   3. I2EM_Bistat_model evaluates the incidence at theta + 0.01 rad (0.57 deg; a guard against
#      theta = 0, while the scattering angle stays at theta_s): its "backscatter" is 0.57 deg
#      bistatic. Every case here has theta >= 12 deg, so the guard is removed and the code is
#      compared at the angles asked. GUARD=kept writes reference_copol_published.csv instead.
set -euo pipefail
book=$(cd "$1" && pwd); kind=${2:-copol}; here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
cp "$book/I2EM_Bistat_model.m" "$book/IEMX_model.m" "$work/"
sed -i 's/= dblquad(@(Zx, Zy)/= cdblquad(@(Zx, Zy)/' "$work/I2EM_Bistat_model.m"
if [ "${GUARD:-removed}" = removed ]; then  # 3. the incidence guard theta + 0.01 rad (see the header) removed
    sed -i "s/cos(theta+ 0.01)/cos(theta)/; s/sin(theta+ 0.01)/sin(theta)/" "$work/I2EM_Bistat_model.m"
    grep -q "cs = cos(theta);" "$work/I2EM_Bistat_model.m"
fi
sed -i "s/dblquad(@(r,phi)xpol_integralfunc(r, \(.*\)), 0.1, 1, 0, pi)/dblquad(@(r,phi) reshape(xpol_integralfunc(r(:).', \1), size(r)), 0.1, 1, 0, pi)/" \
    "$work/IEMX_model.m"
grep -q cdblquad "$work/I2EM_Bistat_model.m" && grep -q "reshape(xpol" "$work/IEMX_model.m"
cat > "$work/cdblquad.m" <<'OCT'
function q = cdblquad(f, xa, xb, ya, yb)
  q = dblquad(@(x, y) real(f(x, y)), xa, xb, ya, yb) + 1i * dblquad(@(x, y) imag(f(x, y)), xa, xb, ya, yb);
end
OCT
cat > "$work/run_cases.m" <<'OCT'
args = argv(); kind = args{1}; src = args{2}; dst = args{3};
c = csvread(src, 1, 0); out = fopen(dst, "w");
if strncmp(kind, "copol", 5)
  fprintf(out, "frequency_ghz,rms_height_m,correlation_length_m,theta_i_deg,theta_s_deg,phi_s_deg,eps_re,eps_im,correlation,vv_db,hh_db\n");
  for i = 1:rows(c)
    [vv, hh] = I2EM_Bistat_model(c(i,1), c(i,2), c(i,3), c(i,4), c(i,5), c(i,6), c(i,7) - 1i * c(i,8), c(i,9), 1.5);
    fprintf(out, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d,%.10g,%.10g\n", c(i,1:8), c(i,9), real(vv), real(hh));
  end
else
  fprintf(out, "frequency_ghz,rms_height_m,correlation_length_m,theta_deg,eps_re,eps_im,correlation,hv_db\n");
  for i = 1:rows(c)
    hv = IEMX_model(c(i,1), c(i,2), c(i,3), c(i,4), c(i,5) - 1i * c(i,6), c(i,7), 1.5, 1);
    fprintf(out, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d,%.10g\n", c(i,1:6), c(i,7), real(hv));
    fflush(out);
  end
end
fclose(out);
OCT
name=reference_$kind; [ "${GUARD:-removed}" = removed ] || name=${name}_published
(cd "$work" && octave --no-gui -q run_cases.m "$kind" "$here/cases_$kind.csv" "$here/$name.csv")
echo "wrote $here/$name.csv"
