!> Failure and softening laws of the springs (docs/model.md, "Fracture"): for each material
!> the strains where tension, crushing and shear damage begin and where their softening
!> ends (the crack band: the softening strain scaled by the cell size so that a band of cells
!> dissipates the fracture energy per unit crack area), and the intact factor of a spring for
!> the largest strain it has reached.
module iem_fracture_law
  use iem_kinds, only: wp
  use iem_spring_constants, only: spring_moduli
  implicit none
  private
  public :: fracture_law_t, fracture_law, softening_factor, band_stress, largest_band
  public :: crit_tension, crit_crushing, crit_shear, no_onset, soft_linear, soft_bilinear

  !> Softening shapes: linear, or bilinear (Petersson 1981: in crack opening w, from f_t to
  !> f_t/3 at w = 0.8 G_f/f_t, then to 0 at w = 3.6 G_f/f_t).
  integer, parameter :: soft_linear = 1, soft_bilinear = 2

  !> The three criteria: edge springs in tension, edge springs crushed, shear springs.
  integer, parameter :: crit_tension = 1, crit_crushing = 2, crit_shear = 3
  !> Onset strain of a criterion that is off.
  real(wp), parameter :: no_onset = huge(1.0_wp)

  !> The failure law of one material. onset(i): the strain where damage of criterion i
  !> begins (no_onset: off); final(d, i): where its softening ends for a band across the
  !> edges of direction d (1: x edges, band width lx; 2: y edges, width ly; shear: both the
  !> same, width sqrt(lx ly)); knee(d, i): the strain of the bilinear law's knee (0: linear);
  !> r = Hq/Eq of the edge and Poisson springs; phi1 = the uniaxial modulus over Eq (so that
  !> a band in uniaxial stress follows the stated law exactly).
  type :: fracture_law_t
    real(wp) :: onset(3) = no_onset
    real(wp) :: final(2, 3) = no_onset
    real(wp) :: knee(2, 3) = 0.0_wp
    real(wp) :: r = 0.0_wp, phi1 = 1.0_wp
  end type fracture_law_t

contains

  !> The law of a material with Young's modulus young, Poisson's ratio poisson (plane strain
  !> or stress) on cells lx x ly: for each criterion i its strength(i) (Pa) or limit strain
  !> strain(i) (used when strength(i) <= 0; both <= 0: the criterion is off) and fracture
  !> energy energy(i) (J/m^2), softening linear or bilinear (shape; default linear). ok =
  !> .false. when a softening branch would snap back (then bad is the first such criterion).
  pure subroutine fracture_law(young, poisson, plane_strain, lx, ly, strength, strain, energy, &
                               law, ok, bad, shape)
    real(wp), intent(in) :: young, poisson, lx, ly, strength(3), strain(3), energy(3)
    logical, intent(in) :: plane_strain
    type(fracture_law_t), intent(out) :: law
    logical, intent(out) :: ok
    integer, intent(out) :: bad
    integer, intent(in), optional :: shape
    real(wp) :: m(3), modulus, f, h(2)
    integer :: i
    m = spring_moduli(young, poisson, plane_strain)
    law%r = m(2)/m(1)
    law%phi1 = (1.0_wp + 4.0_wp*law%r)/(1.0_wp + 2.0_wp*law%r)
    ok = .true.
    bad = 0
    do i = 1, 3
      if (strength(i) <= 0.0_wp .and. strain(i) <= 0.0_wp) cycle
      if (i == crit_shear) then
        modulus = 2.0_wp*m(3)
        h = sqrt(lx*ly)
      else
        modulus = law%phi1*m(1)
        h = [lx, ly]
      end if
      if (strength(i) > 0.0_wp) then
        f = strength(i)
        law%onset(i) = f/modulus
      else
        law%onset(i) = strain(i)
        f = strain(i)*modulus
      end if
      ! linear softening from (onset, f) to (final, 0) encloses energy/h; bilinear: the band
      ! strain is the elastic strain plus the opening over h, the knee at (f/3, 0.8 G/f)
      law%final(:, i) = 2.0_wp*energy(i)/(f*h)
      if (present(shape)) then
        if (shape == soft_bilinear) then
          law%final(:, i) = 3.6_wp*energy(i)/(f*h)
          law%knee(:, i) = law%onset(i)/3.0_wp + 0.8_wp*energy(i)/(f*h)
        end if
      end if
      if ((any(law%final(:, i) <= law%onset(i)) .or. any(law%knee(:, i) > 0.0_wp .and. &
          law%knee(:, i) <= law%onset(i))) .and. ok) then
        ok = .false.
        bad = i
      end if
    end do
  end subroutine fracture_law

  !> The largest band width (m) whose softening branch does not snap back for a criterion of
  !> onset strain eps0 and fracture energy gf on a modulus (uniaxial for edges, G for shear):
  !> 2 G E/f^2 for linear softening, 1.2 G E/f^2 for bilinear (its knee must pass the onset).
  pure real(wp) function largest_band(modulus, eps0, gf, shape)
    real(wp), intent(in) :: modulus, eps0, gf
    integer, intent(in), optional :: shape
    largest_band = 2.0_wp*gf/(modulus*eps0**2)
    if (present(shape)) then
      if (shape == soft_bilinear) largest_band = 1.2_wp*gf/(modulus*eps0**2)
    end if
  end function largest_band

  !> The band's stress over its strength at strain kappa for the softening law (1 up to
  !> eps0, then linearly to 0 at epsf, 0 beyond; with knee > eps0, bilinear: to 1/3 at knee,
  !> then to 0 at epsf), divided by kappa/eps0: the secant over the initial modulus the band
  !> must have.
  pure real(wp) function band_stress(kappa, eps0, epsf, knee) result(ratio)
    real(wp), intent(in) :: kappa, eps0, epsf
    real(wp), intent(in), optional :: knee
    real(wp) :: e1
    e1 = 0.0_wp
    if (present(knee)) e1 = knee
    if (kappa <= eps0) then
      ratio = 1.0_wp
    else if (kappa >= epsf) then
      ratio = 0.0_wp
    else if (e1 <= eps0) then
      ratio = (eps0/kappa)*(epsf - kappa)/(epsf - eps0)
    else if (kappa <= e1) then
      ratio = (eps0/kappa)*(1.0_wp - (2.0_wp/3.0_wp)*(kappa - eps0)/(e1 - eps0))
    else
      ratio = (eps0/kappa)*(epsf - kappa)/(3.0_wp*(epsf - e1))
    end if
  end function band_stress

  !> Intact factor a in [0, 1] of a spring whose largest strain is kappa, for a criterion
  !> with onset eps0 and end epsf. For edges (r, phi1 of the law) a is chosen so that a band
  !> of cells in uniaxial stress, its edges across the band at factor a and the Poisson and
  !> shear springs that use them too, has the secant band_stress: the uniaxial modulus of
  !> such a band over Eq is a(1+2r) - 4 r^2 a^2/(1+2ra), so a solves
  !> 2r a^2 + (1+2r-2rT) a - T = 0 with T = phi1*band_stress. For shear springs r = 0,
  !> phi1 = 1: a = band_stress. knee: that of a bilinear law (absent or 0: linear).
  pure real(wp) function softening_factor(kappa, eps0, epsf, r, phi1, knee) result(a)
    real(wp), intent(in) :: kappa, eps0, epsf, r, phi1
    real(wp), intent(in), optional :: knee
    real(wp) :: tt, b
    if (kappa <= eps0) then
      a = 1.0_wp
    else if (kappa >= epsf) then
      a = 0.0_wp
    else
      tt = phi1*band_stress(kappa, eps0, epsf, knee)
      b = 1.0_wp + 2.0_wp*r - 2.0_wp*r*tt
      a = 2.0_wp*tt/(b + sqrt(b*b + 8.0_wp*r*tt))
      a = min(1.0_wp, max(0.0_wp, a))
    end if
  end function softening_factor
end module iem_fracture_law
