!> Nonlinear springs of the paper's cell: each of a cell's 12 springs (4 edge, 4 Poisson,
!> 4 shear) follows the hyperbolic skeleton with Masing hysteresis (iem_masing), with a
!> reference strain per spring kind and sign mapped from the continuum strengths
!> (docs/nonlinear.md, "Which strength drives which spring"). Holds the springs' history
!> (committed only at accepted states) and the work done on them.
module iem_nonlinear_springs
  use iem_kinds, only: wp, ip
  use iem_masing, only: masing_state_t
  use iem_spring_constants, only: effective_elastic
  use iem_alloc_guard, only: alloc_guard_t
  implicit none
  private
  public :: nonlinear_springs_t, springs_per_cell, spring_kind_edge, spring_kind_poisson
  public :: spring_kind_shear, spring_kind, spring_strains, reference_strains

  !> Springs of one cell, in this order: edges 1..4 (bottom, right, top, left), Poisson
  !> springs at corners 1..4 (SW, SE, NE, NW), shear springs at corners 1..4.
  integer, parameter :: springs_per_cell = 12
  integer, parameter :: spring_kind_edge = 1, spring_kind_poisson = 2, spring_kind_shear = 3

  !> The nonlinear springs of the local cells of one rank.
  type :: nonlinear_springs_t
    !> Reference strains e_r = s_max / E_max per kind (edge, Poisson, shear) and material, for
    !> a positive (tension, or positive shear measure) and a negative strain: (3, materials).
    real(wp), allocatable :: er_pos(:, :), er_neg(:, :)
    !> Twice the energy coefficient of each kind (2 ce, 2 ch, 2 cg) and material: the spring's
    !> generalised force is this times its normalised stress psi (stress / E_max, a strain).
    real(wp), allocatable :: c2(:, :)
    !> History of every spring: spring j of local cell c is entry 12 (c - 1) + j; its stress
    !> is stored normalised by E_max.
    type(masing_state_t) :: state
    !> Work done on each spring up to its committed strain (J): stored plus dissipated.
    real(wp), allocatable :: work(:)
  contains
    procedure :: init => nonlinear_springs_init
    procedure :: set_law => nonlinear_springs_set_law
  end type nonlinear_springs_t

contains

  !> The kind (edge, Poisson, shear) of spring j = 1..12 of a cell.
  pure integer function spring_kind(j) result(kind)
    integer, intent(in) :: j
    kind = (j - 1)/4 + 1
  end function spring_kind

  !> Reference strains (positive, negative) of the three spring kinds from the continuum
  !> strengths: edge springs reach half their secant stiffness at the uniaxial strain f/E'
  !> (f_t in tension, f_c in compression), Poisson springs at (1 - nu') f/E' (their strain in
  !> uniaxial stress is (1 - nu') times the edge's, so both soften together), shear springs at
  !> tau/G for either sign. E' = E, nu' = nu in plane stress; E/(1 - nu^2), nu/(1 - nu) in
  !> plane strain.
  pure subroutine reference_strains(young, poisson, plane_strain, f_t, f_c, tau, er_pos, er_neg)
    real(wp), intent(in) :: young, poisson, f_t, f_c, tau
    logical, intent(in) :: plane_strain
    real(wp), intent(out) :: er_pos(3), er_neg(3)
    real(wp) :: e, nu, g
    call effective_elastic(young, poisson, plane_strain, e, nu)
    g = young/(2.0_wp*(1.0_wp + poisson))
    er_pos = [f_t/e, (1.0_wp - nu)*f_t/e, tau/g]
    er_neg = [f_c/e, (1.0_wp - nu)*f_c/e, tau/g]
  end subroutine reference_strains

  !> Allocate the virgin springs of n_cells cells, with the reference strains, the energy
  !> coefficients (ce, ch, cg) of material 1 and the stack depth of their history; with
  !> n_materials (default 1), set_law gives the others. Out of memory: noted in guard (the
  !> springs are then incomplete), or the program stops without one.
  subroutine nonlinear_springs_init(this, n_cells, er_pos, er_neg, coeffs, depth, guard, &
                                    n_materials)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: n_cells, depth
    real(wp), intent(in) :: er_pos(3), er_neg(3), coeffs(3)
    type(alloc_guard_t), intent(inout), optional :: guard
    integer, intent(in), optional :: n_materials
    type(alloc_guard_t) :: g
    integer(ip) :: st
    integer :: ierr, nm
    real(wp) :: bytes
    nm = 1
    if (present(n_materials)) nm = n_materials
    if (allocated(this%er_pos)) deallocate(this%er_pos, this%er_neg, this%c2)
    allocate(this%er_pos(3, nm), this%er_neg(3, nm), this%c2(3, nm))
    this%er_pos = 0.0_wp
    this%er_neg = 0.0_wp
    this%c2 = 0.0_wp
    call this%set_law(1, er_pos, er_neg, coeffs)
    bytes = real(springs_per_cell, wp)*n_cells*(48.0_wp + 16.0_wp*depth)
    call this%state%init(int(springs_per_cell*n_cells, ip), int(depth, ip), st)
    call g%note(int(st), 'the nonlinear springs of the rank', bytes)
    if (allocated(this%work)) deallocate(this%work)
    if (.not. g%failed) then
      allocate(this%work(springs_per_cell*n_cells), stat=ierr)
      call g%note(ierr, 'the nonlinear springs of the rank', bytes)
    end if
    if (g%failed) then
      call g%pass(guard)
      return
    end if
    this%work = 0.0_wp
  end subroutine nonlinear_springs_init

  !> Set the reference strains and energy coefficients (ce, ch, cg) of material m.
  pure subroutine nonlinear_springs_set_law(this, m, er_pos, er_neg, coeffs)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: m
    real(wp), intent(in) :: er_pos(3), er_neg(3), coeffs(3)
    this%er_pos(:, m) = er_pos
    this%er_neg(:, m) = er_neg
    this%c2(:, m) = 2.0_wp*coeffs
  end subroutine nonlinear_springs_set_law

  !> The 12 spring strains of a cell from its edge strains ep(4) and corner shear measures
  !> s(4): edges, Poisson springs (corner q: edge q + edge q-1), shear springs.
  pure function spring_strains(ep, s) result(e)
    real(wp), intent(in) :: ep(4), s(4)
    real(wp) :: e(springs_per_cell)
    e = [ep, ep(1) + ep(4), ep(2) + ep(1), ep(3) + ep(2), ep(4) + ep(3), s]
  end function spring_strains
end module iem_nonlinear_springs
