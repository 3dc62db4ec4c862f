!> The fracture state of one rank's cells (docs/model.md, "Fracture"): each cell's largest
!> strains reached by its springs (the history that sets their intact factors), the time each
!> of its edge and shear springs failed, and the energy its damage has dissipated. Allocated
!> only when a material may fracture or a shape pre-cuts cells; the force kernel reads it
!> only for cells whose damage has begun or whose trial strains pass an onset.
module iem_fracture
  use iem_kinds, only: wp
  use iem_fracture_law, only: fracture_law_t, no_onset, softening_factor, crit_tension, &
                              crit_crushing, crit_shear
  use iem_shapes, only: shape_t, shape_contains
  use iem_alloc_guard, only: alloc_guard_t
  implicit none
  private
  public :: fracture_t, intact_time, precut_kappa, edge_factor, shear_factor, failure_kind
  public :: fail_tension, fail_crushing, fail_shear, fail_precut

  !> Failure time of a spring that has not failed.
  real(wp), parameter :: intact_time = huge(1.0_wp)
  !> The largest strain recorded for the edges of a pre-cut cell (their factor is 0).
  real(wp), parameter :: precut_kappa = huge(1.0_wp)
  !> How a spring failed (output and event log): tension, crushing, shear, pre-cut.
  integer, parameter :: fail_tension = 1, fail_crushing = 2, fail_shear = 3, fail_precut = 4

  !> Per-cell fracture state of a rank (local cells, in the lattice's cell order).
  type :: fracture_t
    !> Whether any cell can be damaged (a material with a criterion, or a pre-cut cell).
    logical :: active = .false.
    !> The law of each material (a material without fracture has every onset at no_onset).
    type(fracture_law_t), allocatable :: laws(:)
    !> The smallest onset of each criterion over the materials (the kernel's quick test).
    real(wp) :: onset_min(3) = no_onset
    !> kappa(1:4, c): largest tensile strain of edges 1..4; (5:8): largest compressive
    !> strain (positive) of edges 1..4; (9:12): largest |shear measure| of corners 1..4.
    real(wp), allocatable :: kappa(:, :)
    !> t_fail(1:4, c): time edge q failed (its factor reached 0); (5:8): time the shear spring
    !> of corner q failed by its own criterion; intact_time while intact.
    real(wp), allocatable :: t_fail(:, :)
    !> Energy each cell's damage has dissipated (J), summed at accepted states.
    real(wp), allocatable :: diss(:)
    !> e_prev(1:4, c): edge strains, (5:8): shear measures of the cell's last accepted state,
    !> kept once its damage has begun (the start of the next step's strain path).
    real(wp), allocatable :: e_prev(:, :)
    !> Whether the cell's damage has begun (derived from kappa: see refresh).
    logical, allocatable :: hit(:)
    !> Whether some cell of the rank may have been hit (.false.: none has; the kernel then
    !> skips its test of hit): set with every hit(c) = .true., and by refresh.
    logical :: any_hit = .false.
  contains
    procedure :: init => fracture_init
    procedure :: precut => fracture_precut
    procedure :: refresh => fracture_refresh
    procedure :: free => fracture_free
  end type fracture_t

contains

  !> Set up the state of n_cells intact cells with the laws of the materials.
  subroutine fracture_init(this, laws, n_cells, guard)
    class(fracture_t), intent(inout) :: this
    type(fracture_law_t), intent(in) :: laws(:)
    integer, intent(in) :: n_cells
    type(alloc_guard_t), intent(inout) :: guard
    integer :: ierr, i
    call this%free()
    this%active = .true.
    this%laws = laws
    do i = 1, 3
      this%onset_min(i) = minval(laws(:)%onset(i))
    end do
    allocate(this%kappa(12, n_cells), this%t_fail(8, n_cells), this%diss(n_cells), &
             this%e_prev(8, n_cells), this%hit(n_cells), stat=ierr)
    call guard%note(ierr, 'the fracture state of the rank', 236.0_wp*n_cells)
    if (guard%failed) return
    this%kappa = 0.0_wp
    this%t_fail = intact_time
    this%diss = 0.0_wp
    this%e_prev = 0.0_wp
    this%hit = .false.
    this%any_hit = .false.
  end subroutine fracture_init

  !> Fail every edge (and so every spring) of the cells whose centre one of the shapes holds
  !> (cells(2, :): cell centres of the local cells).
  subroutine fracture_precut(this, shapes, centres)
    class(fracture_t), intent(inout) :: this
    type(shape_t), intent(in) :: shapes(:)
    real(wp), intent(in) :: centres(:, :)
    integer :: c, k
    do c = 1, size(centres, 2)
      do k = 1, size(shapes)
        if (shape_contains(shapes(k), centres(1, c), centres(2, c))) then
          this%kappa(1:4, c) = precut_kappa
          this%t_fail(1:4, c) = 0.0_wp
          this%hit(c) = .true.
          this%any_hit = .true.
          exit
        end if
      end do
    end do
  end subroutine fracture_precut

  !> Recompute hit from kappa (after the state was read back from a checkpoint or moved);
  !> cell_mat: each cell's material (empty: every cell's is 1).
  subroutine fracture_refresh(this, cell_mat)
    class(fracture_t), intent(inout) :: this
    integer, intent(in) :: cell_mat(:)
    integer :: c, mt
    if (size(this%hit) /= size(this%kappa, 2)) then
      deallocate(this%hit)
      allocate(this%hit(size(this%kappa, 2)))
    end if
    do c = 1, size(this%hit)
      mt = 1
      if (size(cell_mat) > 0) mt = cell_mat(c)
      associate(lw => this%laws(mt))
        this%hit(c) = any(this%kappa(1:4, c) == precut_kappa) .or. &
                      any(this%kappa(1:4, c) > lw%onset(crit_tension)) .or. &
                      any(this%kappa(5:8, c) > lw%onset(crit_crushing)) .or. &
                      any(this%kappa(9:12, c) > lw%onset(crit_shear))
      end associate
    end do
    this%any_hit = any(this%hit)
  end subroutine fracture_refresh

  !> Release the state.
  subroutine fracture_free(this)
    class(fracture_t), intent(inout) :: this
    this%active = .false.
    this%any_hit = .false.
    if (allocated(this%laws)) deallocate(this%laws)
    if (allocated(this%kappa)) deallocate(this%kappa)
    if (allocated(this%t_fail)) deallocate(this%t_fail)
    if (allocated(this%diss)) deallocate(this%diss)
    if (allocated(this%e_prev)) deallocate(this%e_prev)
    if (allocated(this%hit)) deallocate(this%hit)
  end subroutine fracture_free

  !> Intact factor of edge q (1..4) of a cell of law lw whose strain history is kap(12):
  !> the product of its tension and crushing factors (x edges: q odd, band width lx).
  pure real(wp) function edge_factor(lw, kap, q) result(a)
    type(fracture_law_t), intent(in) :: lw
    real(wp), intent(in) :: kap(12)
    integer, intent(in) :: q
    integer :: d
    d = 2 - mod(q, 2)
    a = 1.0_wp
    if (kap(q) == precut_kappa) then
      a = 0.0_wp
      return
    end if
    if (kap(q) > lw%onset(crit_tension)) a = softening_factor(kap(q), lw%onset(crit_tension), &
      lw%final(d, crit_tension), lw%r, lw%phi1, lw%knee(d, crit_tension))
    if (kap(4 + q) > lw%onset(crit_crushing)) a = a*softening_factor(kap(4 + q), &
      lw%onset(crit_crushing), lw%final(d, crit_crushing), lw%r, lw%phi1, &
      lw%knee(d, crit_crushing))
  end function edge_factor

  !> Intact factor of the shear spring of corner q by its own criterion.
  pure real(wp) function shear_factor(lw, kap, q) result(a)
    type(fracture_law_t), intent(in) :: lw
    real(wp), intent(in) :: kap(12)
    integer, intent(in) :: q
    a = 1.0_wp
    if (kap(8 + q) > lw%onset(crit_shear)) a = softening_factor(kap(8 + q), &
      lw%onset(crit_shear), lw%final(1, crit_shear), 0.0_wp, 1.0_wp, lw%knee(1, crit_shear))
  end function shear_factor

  !> How spring j (1..4: edge j; 5..8: the shear spring of corner j-4, by its own criterion)
  !> of a cell of law lw with strain history kap(12) has failed: fail_precut, fail_tension or
  !> fail_crushing (the criterion whose factor reached 0; tension when both did), fail_shear;
  !> 0 while that factor is not 0.
  pure integer function failure_kind(lw, kap, j) result(how)
    type(fracture_law_t), intent(in) :: lw
    real(wp), intent(in) :: kap(12)
    integer, intent(in) :: j
    integer :: d
    how = 0
    if (j > 4) then
      if (shear_factor(lw, kap, j - 4) == 0.0_wp) how = fail_shear
      return
    end if
    d = 2 - mod(j, 2)
    if (kap(j) == precut_kappa) then
      how = fail_precut
    else if (kap(j) > lw%onset(crit_tension) .and. softening_factor(kap(j), &
             lw%onset(crit_tension), lw%final(d, crit_tension), lw%r, lw%phi1) == 0.0_wp) then
      how = fail_tension
    else if (kap(4 + j) > lw%onset(crit_crushing) .and. softening_factor(kap(4 + j), &
             lw%onset(crit_crushing), lw%final(d, crit_crushing), lw%r, lw%phi1) == 0.0_wp) then
      how = fail_crushing
    end if
  end function failure_kind
end module iem_fracture
