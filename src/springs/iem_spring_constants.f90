!> Spring constants of the IEM cell from energy equivalence (model.md section 2).
module iem_spring_constants
  use iem_kinds, only: wp
  implicit none
  private
  public :: cell_constants_t, spring_moduli, cell_constants, law_paper, law_bending
  public :: effective_elastic

  !> Cell laws: the paper's 12 springs, or the bending-corrected cell (docs/model.md).
  integer, parameter :: law_paper = 1, law_bending = 2

  !> Constants of one cell. Paper's cell: Pi = ce*sum eps^2 + ch*sum (eps_q+eps_{q-1})^2
  !> + cg*sum s^2. Bending-corrected cell: Pi = 2ce(ex^2+ey^2) + 4ch(ex+ey)^2 + 4cg g^2
  !> + cb(dx^2+dy^2) with mean strains ex, ey, mean shear g and edge differences dx, dy.
  type :: cell_constants_t
    integer :: law = law_paper
    real(wp) :: lx = 0.0_wp, ly = 0.0_wp
    !> Inverse reference lengths of edges 1..4 (bottom, right, top, left).
    real(wp) :: il0(4) = 0.0_wp
    real(wp) :: ce = 0.0_wp, ch = 0.0_wp, cg = 0.0_wp, cb = 0.0_wp
  end type cell_constants_t

contains

  !> The in-plane modulus and Poisson ratio (E', nu'): (E, nu) in plane stress,
  !> (E/(1 - nu^2), nu/(1 - nu)) in plane strain.
  pure subroutine effective_elastic(young, poisson, plane_strain, e, nu)
    real(wp), intent(in) :: young, poisson
    logical, intent(in) :: plane_strain
    real(wp), intent(out) :: e, nu
    e = young
    nu = poisson
    if (plane_strain) then
      e = young/(1.0_wp - poisson**2)
      nu = poisson/(1.0_wp - poisson)
    end if
  end subroutine effective_elastic

  !> Moduli (Eq, Hq, Gq) of the edge, Poisson and shear springs for plane stress or strain.
  pure function spring_moduli(young, poisson, plane_strain) result(m)
    real(wp), intent(in) :: young, poisson
    logical, intent(in) :: plane_strain
    real(wp) :: m(3)
    real(wp) :: e, nu
    call effective_elastic(young, poisson, plane_strain, e, nu)
    m(1) = e/(1.0_wp + nu)
    m(2) = nu*e/(2.0_wp*(1.0_wp - nu**2))
    m(3) = e/(4.0_wp*(1.0_wp + nu))
  end function spring_moduli

  !> Cell energy coefficients: the moduli times (1/4) S t, with S = lx*ly; with bending, also
  !> the bending spring cb = E' t S / 24 (E' = E, or E/(1-nu^2) in plane strain).
  pure function cell_constants(young, poisson, plane_strain, lx, ly, thickness, bending) &
      result(k)
    real(wp), intent(in) :: young, poisson, lx, ly, thickness
    logical, intent(in) :: plane_strain
    logical, intent(in), optional :: bending
    type(cell_constants_t) :: k
    real(wp) :: m(3), s
    m = spring_moduli(young, poisson, plane_strain)
    s = 0.25_wp*lx*ly*thickness
    k%lx = lx
    k%ly = ly
    k%il0 = 1.0_wp/[lx, ly, lx, ly]
    k%ce = s*m(1)
    k%ch = s*m(2)
    k%cg = s*m(3)
    k%law = law_paper
    if (present(bending)) then
      if (bending) k%law = law_bending
    end if
    if (k%law == law_bending) then
      k%cb = young*thickness*lx*ly/24.0_wp
      if (plane_strain) k%cb = k%cb/(1.0_wp - poisson**2)
    end if
  end function cell_constants
end module iem_spring_constants
