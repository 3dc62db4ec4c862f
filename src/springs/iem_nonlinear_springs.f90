!> Nonlinear springs of the paper's cell: each of a cell's 12 springs (4 edge, 4 Poisson,
!> 4 shear) follows the hyperbolic skeleton with Masing hysteresis (iem_masing), with a
!> reference strain per spring kind and sign mapped from the continuum strengths
!> (docs/nonlinear.md, "Which strength drives which spring"). Holds the springs' history
!> (committed only at accepted states), the work done on them, and the curve each is on
!> (iem_masing's masing_curve), with which the springs of a chunk of cells are evaluated and
!> committed in vectorised loops (docs/nonlinear.md, section 6a).
module iem_nonlinear_springs
  use iem_kinds, only: wp, ip
  use iem_masing, only: masing_state_t, masing_curve, masing_trial, masing_commit, &
                        masing_constants, n_masing_constants, k_pos, k_neg, k_branch, &
                        k_mirror_pos, k_mirror_neg
  use iem_masing_fast, only: fast_stresses, fast_commit, n_q, q_half_energy, n_commit_real, &
                             n_commit_int, c_strain, c_stress, c_max_pos, c_max_neg, c_ps, c_e0, &
                             c_s0, c_hk, c_lo, c_hi, c_count, c_dir
  use iem_spring_constants, only: effective_elastic
  use iem_masing_simd, only: masing_simd, c_curve_commit, c_curve_stress
  use iem_alloc_guard, only: alloc_guard_t
  implicit none
  private
  public :: nonlinear_springs_t, springs_per_cell, spring_kind_edge, spring_kind_poisson
  public :: spring_kind_shear, spring_kind, spring_strains, reference_strains
  public :: chunk_cells

  !> Springs of one cell, in this order: edges 1..4 (bottom, right, top, left), Poisson
  !> springs at corners 1..4 (SW, SE, NE, NW), shear springs at corners 1..4.
  integer, parameter :: springs_per_cell = 12
  integer, parameter :: spring_kind_edge = 1, spring_kind_poisson = 2, spring_kind_shear = 3
  !> Cells of a chunk of the force kernel (iem_cell_laws' chunk): the rows of the table q;
  !> stress and commit take at most max_springs springs at a time.
  integer, parameter :: chunk_cells = 64, max_springs = springs_per_cell*chunk_cells
  !> Columns of the springs' curves (nonlinear_springs_t's cv).
  integer, parameter :: cv_lo = 1, cv_hi = 2, cv_e0 = 3, cv_s0 = 4, cv_hk = 5, cv_ps = 6, &
                        n_cv = 6

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
    !> The constants of the springs of a chunk of cells of one material: q(k, :, material)
    !> for spring k = 12 (c - 1) + j of the chunk (spring j of its cell c), c = 1..chunk_cells.
    real(wp), allocatable :: q(:, :, :)
    !> The curve each spring is on (masing_curve, per spring as the state): the interval
    !> (lo, hi) of the strains a move ends on the curve it starts on, the start (e0, s0) and
    !> scale hk of the curve a move continues on, and the direction ps of a move that pushes
    !> a reversal. Derived from the state, not saved: a cell's are made when first needed
    !> after ready(cell) was cleared (init, stale). Spring i's are cv(i, cv_lo .. cv_ps); the
    !> leading dimension (curve_rows) puts the columns, and column 0 (unused) ahead of them,
    !> in different sets of the first-level cache: the loops over a chunk's springs read
    !> them at once with the state's arrays, which all start alike on their pages where the
    !> allocator maps each one (large arrays).
    real(wp), allocatable :: cv(:, :)
    logical, allocatable :: ready(:)
    !> Number of cells whose curves are made.
    integer :: n_ready = 0
    !> Whether the springs keep their curves (for runs with trial evaluations between commits;
    !> a run that commits every evaluation reads the top of each stack instead).
    logical :: curves = .true.
  contains
    procedure :: init => nonlinear_springs_init
    procedure :: set_law => nonlinear_springs_set_law
    procedure :: stale => nonlinear_springs_stale
    procedure :: prepare => nonlinear_springs_prepare
    procedure :: stress => nonlinear_springs_stress
    procedure :: commit => nonlinear_springs_commit
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
                                    n_materials, curves)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: n_cells, depth
    real(wp), intent(in) :: er_pos(3), er_neg(3), coeffs(3)
    type(alloc_guard_t), intent(inout), optional :: guard
    integer, intent(in), optional :: n_materials
    !> Keep the springs' curves (default: yes).
    logical, intent(in), optional :: curves
    type(alloc_guard_t) :: g
    integer(ip) :: st
    integer :: ierr, nm, j, n
    real(wp) :: bytes
    nm = 1
    if (present(n_materials)) nm = n_materials
    this%curves = .true.
    if (present(curves)) this%curves = curves
    if (allocated(this%er_pos)) deallocate(this%er_pos, this%er_neg, this%c2, this%q)
    allocate(this%er_pos(3, nm), this%er_neg(3, nm), this%c2(3, nm), &
             this%q(springs_per_cell*chunk_cells, n_q, nm))
    ! a material whose law is not set: reference strains 1, no energy
    do j = 1, nm
      call this%set_law(j, [1.0_wp, 1.0_wp, 1.0_wp], [1.0_wp, 1.0_wp, 1.0_wp], &
                        [0.0_wp, 0.0_wp, 0.0_wp])
    end do
    call this%set_law(1, er_pos, er_neg, coeffs)
    bytes = real(springs_per_cell, wp)*n_cells*(merge(104.0_wp, 48.0_wp, this%curves) + &
                                                16.0_wp*depth)
    call this%state%init(int(springs_per_cell*n_cells, ip), int(depth, ip), st)
    call g%note(int(st), 'the nonlinear springs of the rank', bytes)
    if (allocated(this%work)) deallocate(this%work, this%cv, this%ready)
    if (.not. g%failed) then
      n = springs_per_cell*n_cells
      if (.not. this%curves) n = 0
      allocate(this%work(springs_per_cell*n_cells), this%cv(curve_rows(n), 0:n_cv), &
               this%ready(merge(n_cells, 0, this%curves)), &
               stat=ierr)
      call g%note(ierr, 'the nonlinear springs of the rank', bytes)
    end if
    if (g%failed) then
      call g%pass(guard)
      return
    end if
    this%work = 0.0_wp
    call this%stale()
  end subroutine nonlinear_springs_init

  !> Mark every cell's curves as to be made again from the state: after the state was set
  !> other than by commit (a restart, a repartitioning).
  pure subroutine nonlinear_springs_stale(this)
    class(nonlinear_springs_t), intent(inout) :: this
    if (allocated(this%ready)) this%ready = .false.
    this%n_ready = 0
  end subroutine nonlinear_springs_stale

  !> Set the reference strains and energy coefficients (ce, ch, cg) of material m.
  pure subroutine nonlinear_springs_set_law(this, m, er_pos, er_neg, coeffs)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: m
    real(wp), intent(in) :: er_pos(3), er_neg(3), coeffs(3)
    integer :: k, kind
    this%er_pos(:, m) = er_pos
    this%er_neg(:, m) = er_neg
    this%c2(:, m) = 2.0_wp*coeffs
    do k = 1, springs_per_cell*chunk_cells
      kind = spring_kind(mod(k - 1, springs_per_cell) + 1)
      this%q(k, 1:n_masing_constants, m) = masing_constants(er_pos(kind), er_neg(kind))
      this%q(k, q_half_energy, m) = 0.5_wp*this%c2(kind, m)
    end do
  end subroutine nonlinear_springs_set_law

  !> The 12 spring strains of a cell from its edge strains ep(4) and corner shear measures
  !> s(4): edges, Poisson springs (corner q: edge q + edge q-1), shear springs.
  pure function spring_strains(ep, s) result(e)
    real(wp), intent(in) :: ep(4), s(4)
    real(wp) :: e(springs_per_cell)
    e = [ep, ep(1) + ep(4), ep(2) + ep(1), ep(3) + ep(2), ep(4) + ep(3), s]
  end function spring_strains

  !> Make the curves of those of the cells c_first .. c_first + m - 1 whose curves are not
  !> ready; spring k of the chunk (spring j of its cell c at 12 (c - 1) + j) has the
  !> constants p(k, :) (the table q of its material, or such rows).
  pure subroutine nonlinear_springs_prepare(this, c_first, m, p)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: c_first, m
    real(wp), intent(in), contiguous :: p(:, :)
    integer :: c, j, k
    if (this%n_ready == size(this%ready)) return
    do c = 1, m
      if (this%ready(c_first + c - 1)) cycle
      do j = 1, springs_per_cell
        k = springs_per_cell*(c - 1) + j
        call make_curve(this, springs_per_cell*(c_first - 1) + k, p(k, k_mirror_pos), &
                        p(k, k_mirror_neg))
      end do
      this%ready(c_first + c - 1) = .true.
      this%n_ready = this%n_ready + 1
    end do
  end subroutine nonlinear_springs_prepare

  !> Normalised stresses s(k) of the springs i0 + k, k = 1..n (constants p(k, :), curves
  !> ready) at the strains e(k), each reached monotonically from its committed state, bit for
  !> bit masing_trial's; the state is not changed. mv(k) gives the kind of each move: 0 on its
  !> curve (or none), 1 a push on to a new branch (both from a branch-free vectorised loop),
  !> 2 (n_slow of them) the state machine's (in iem_masing_curves_simd.c too where it is built
  !> with AVX2).
  pure subroutine nonlinear_springs_stress(this, i0, n, e, p, s, mv, n_slow)
    class(nonlinear_springs_t), intent(in) :: this
    integer, intent(in) :: i0, n
    real(wp), intent(in) :: e(n)
    real(wp), intent(in), contiguous :: p(:, :)
    real(wp), intent(out) :: s(n), mv(n)
    integer, intent(out) :: n_slow
    real(wp) :: tan
    ! (fixed sizes: no allocation in the time loop)
    integer :: list(max_springs), k, i, m
    if (n > max_springs) error stop 'nonlinear_springs_stress: more than max_springs springs'
    associate(st => this%state, j => i0 + 1, l => i0 + n)
      if (masing_simd()) then
        ! the same loop in AVX2 vectors, the state machine's trials in C too
        ! (iem_masing_curves_simd.c)
        call c_curve_stress(n, int(st%depth), e, p(1:n, k_pos), p(1:n, k_neg), &
                            p(1:n, k_branch), p(1:n, k_mirror_pos), p(1:n, k_mirror_neg), &
                            st%strain(j:l), st%stress(j:l), st%dir(j:l), st%count(j:l), &
                            st%e_rev(:, j:l), st%s_rev(:, j:l), this%cv(j:l, cv_ps), &
                            this%cv(j:l, cv_e0), this%cv(j:l, cv_s0), this%cv(j:l, cv_hk), &
                            this%cv(j:l, cv_lo), this%cv(j:l, cv_hi), s, mv, list, n_slow)
        return
      end if
      call fast_stresses(n, e, p, size(p, 1), 0, st%strain(j:l), st%stress(j:l), &
                         this%cv(j:l, cv_ps), this%cv(j:l, cv_e0), this%cv(j:l, cv_s0), &
                         this%cv(j:l, cv_hk), this%cv(j:l, cv_lo), this%cv(j:l, cv_hi), s, mv)
    end associate
    call moves_from(n, mv, 2.0_wp, list, n_slow)
    do m = 1, n_slow
      k = list(m)
      i = i0 + k
      associate(st => this%state)
        call masing_trial(e(k), 1.0_wp, p(k, k_pos), p(k, k_neg), st%strain(i), st%stress(i), &
                          st%dir(i), st%count(i), st%e_rev(:, i), st%s_rev(:, i), s(k), tan)
      end associate
    end do
  end subroutine nonlinear_springs_stress

  !> Commit the springs i0 + k, k = 1..n (constants p(k, :), curves ready) to the strains
  !> e(k), with their stresses s(k) there, and add the work increments (trapezoidal, from the
  !> committed state) to their work: bit for bit masing_commit. Block by block of springs,
  !> the moves that end on their curve or push on to a new branch are evaluated and
  !> committed in vectorised loops (the pushed points stored between), the others then by
  !> masing_commit, with their curves made again. Where iem_masing_curves_simd.c is built with
  !> AVX2, its curve commit does the vectorised part in one pass, in place, and the state
  !> machine's commits.
  pure subroutine nonlinear_springs_commit(this, i0, n, e, p, s)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: i0, n
    real(wp), intent(in) :: e(n)
    real(wp), intent(out) :: s(n)
    real(wp), intent(in), contiguous :: p(:, :)
    real(wp) :: ec, sc, dw
    integer :: list(max_springs), k, i, m, n_slow
    if (n > max_springs) error stop 'nonlinear_springs_commit: more than max_springs springs'
    associate(st => this%state)
      if (masing_simd()) then
        ! the loops below in one pass of AVX2 vectors, in place, and the state machine's
        ! commits in C (iem_masing_curves_simd.c); then the curves of those
        associate(j => i0 + 1, l => i0 + n)
          call c_curve_commit(n, int(st%depth), e, p(1:n, k_pos), p(1:n, k_neg), &
                              p(1:n, k_branch), p(1:n, k_mirror_pos), p(1:n, k_mirror_neg), &
                              p(1:n, q_half_energy), st%strain(j:l), st%stress(j:l), &
                              st%dir(j:l), st%count(j:l), st%e_rev(:, j:l), st%s_rev(:, j:l), &
                              st%e_max_pos(j:l), st%e_max_neg(j:l), this%cv(j:l, cv_ps), &
                              this%cv(j:l, cv_e0), this%cv(j:l, cv_s0), this%cv(j:l, cv_hk), &
                              this%cv(j:l, cv_lo), this%cv(j:l, cv_hi), this%work(j:l), s, &
                              list, n_slow)
        end associate
        do m = 1, n_slow
          k = list(m)
          call make_curve(this, i0 + k, p(k, k_mirror_pos), p(k, k_mirror_neg))
        end do
        return
      end if
      call commit_loops(this, i0, n, e, p, s, list, n_slow)
      do m = 1, n_slow
        k = list(m)
        i = i0 + k
        ec = st%strain(i)
        sc = st%stress(i)
        call masing_commit(e(k), 1.0_wp, p(k, k_pos), p(k, k_neg), st%strain(i), st%stress(i), &
                           st%dir(i), st%count(i), st%e_rev(:, i), st%s_rev(:, i), &
                           st%e_max_pos(i), st%e_max_neg(i))
        ! the committed stress is bit for bit the trial stress at the same strain
        s(k) = st%stress(i)
        dw = p(k, q_half_energy)*(sc + s(k))*(e(k) - ec)
        this%work(i) = this%work(i) + dw
        call make_curve(this, i, p(k, k_mirror_pos), p(k, k_mirror_neg))
      end do
    end associate
  end subroutine nonlinear_springs_commit

  !> The loops of nonlinear_springs_commit's vectorised part in Fortran (where
  !> iem_masing_simd.c is built without AVX2, or use_masing_simd is cleared): block by block
  !> of springs, fast_stresses and fast_commit into work columns copied back, the pushed
  !> reversal points stored between; the springs left to the state machine in list(1:n_slow).
  pure subroutine commit_loops(this, i0, n, e, p, s, list, n_slow)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: i0, n
    real(wp), intent(in) :: e(n)
    real(wp), intent(in), contiguous :: p(:, :)
    real(wp), intent(out) :: s(n)
    integer, intent(out) :: list(max_springs), n_slow
    ! a block of springs: small enough for its values to stay in the nearest cache between
    ! the loops; the kinds of the moves and the new values
    integer, parameter :: block = 128
    real(wp) :: mv(max_springs), room(block), nr(block, n_commit_real)
    integer(ip) :: ni(block, n_commit_int)
    integer :: i, m, n_off, b, nb
    associate(st => this%state)
      do b = 0, n - 1, block
        nb = min(block, n - b)
        associate(j => i0 + b + 1, l => i0 + b + nb, q => b + 1, r => b + nb)
          call fast_stresses(nb, e(q:r), p, size(p, 1), b, st%strain(j:l), &
                             st%stress(j:l), this%cv(j:l, cv_ps), this%cv(j:l, cv_e0), &
                             this%cv(j:l, cv_s0), this%cv(j:l, cv_hk), this%cv(j:l, cv_lo), &
                             this%cv(j:l, cv_hi), s(q:r), mv(q:r))
          room(1:nb) = real(st%depth - st%count(j:l) - 1, wp)
          call fast_commit(nb, room, e(q:r), p, size(p, 1), b, s(q:r), mv(q:r), &
                           st%strain(j:l), st%stress(j:l), st%dir(j:l), st%count(j:l), &
                           st%e_max_pos(j:l), st%e_max_neg(j:l), this%cv(j:l, cv_ps), &
                           this%cv(j:l, cv_e0), this%cv(j:l, cv_s0), this%cv(j:l, cv_hk), &
                           this%cv(j:l, cv_lo), this%cv(j:l, cv_hi), &
                           this%work(j:l), block, nr, ni)
          ! the reversal points pushed: the committed points before the move
          call moves_from(nb, mv(q:r), 1.0_wp, list, n_off)
          do m = 1, n_off
            if (mv(b + list(m)) /= 1.0_wp) cycle
            i = i0 + b + list(m)
            st%e_rev(st%count(i) + 1, i) = st%strain(i)
            st%s_rev(st%count(i) + 1, i) = st%stress(i)
          end do
          st%strain(j:l) = nr(1:nb, c_strain)
          st%stress(j:l) = nr(1:nb, c_stress)
          st%e_max_pos(j:l) = nr(1:nb, c_max_pos)
          st%e_max_neg(j:l) = nr(1:nb, c_max_neg)
          st%count(j:l) = ni(1:nb, c_count)
          st%dir(j:l) = ni(1:nb, c_dir)
          this%cv(j:l, cv_ps) = nr(1:nb, c_ps)
          this%cv(j:l, cv_e0) = nr(1:nb, c_e0)
          this%cv(j:l, cv_s0) = nr(1:nb, c_s0)
          this%cv(j:l, cv_hk) = nr(1:nb, c_hk)
          this%cv(j:l, cv_lo) = nr(1:nb, c_lo)
          this%cv(j:l, cv_hi) = nr(1:nb, c_hi)
        end associate
      end do
    end associate
    call moves_from(n, mv, 2.0_wp, list, n_slow)
  end subroutine commit_loops

  !> The n_of moves k of kind v or above (mv(k) >= v), in order: list(1:n_of).
  pure subroutine moves_from(n, mv, v, list, n_of)
    integer, intent(in) :: n
    real(wp), intent(in) :: mv(n), v
    integer, intent(out) :: list(n), n_of
    ! groups of four moves: most groups have none (a test of their largest kind), the others
    ! are listed without a branch (each k written, kept when of such a kind)
    integer, parameter :: group = 4
    integer :: k, k0
    n_of = 0
    do k0 = 0, n - group, group
      if (max(max(mv(k0 + 1), mv(k0 + 2)), max(mv(k0 + 3), mv(k0 + 4))) < v) cycle
      do k = k0 + 1, k0 + group
        list(n_of + 1) = k
        n_of = n_of + merge(1, 0, mv(k) >= v)
      end do
    end do
    do k = group*(n/group) + 1, n
      list(n_of + 1) = k
      n_of = n_of + merge(1, 0, mv(k) >= v)
    end do
  end subroutine moves_from

  !> The leading dimension of the curves' array for n springs: n rounded up to 512 (a 4 kB
  !> page of values) and 80 more, so that its columns lie 640 bytes apart modulo a page.
  pure integer function curve_rows(n) result(ld)
    integer, intent(in) :: n
    ld = 0
    if (n > 0) ld = 512*((n + 511)/512) + 80
  end function curve_rows

  !> Make the curve of spring i (mirror factors mp, mn) from its state.
  pure subroutine make_curve(this, i, mp, mn)
    class(nonlinear_springs_t), intent(inout) :: this
    integer, intent(in) :: i
    real(wp), intent(in) :: mp, mn
    associate(st => this%state)
      call masing_curve(st%strain(i), st%dir(i), st%count(i), st%e_rev(:, i), st%s_rev(:, i), &
                        mp, mn, this%cv(i, cv_lo), this%cv(i, cv_hi), this%cv(i, cv_e0), &
                        this%cv(i, cv_s0), this%cv(i, cv_hk), this%cv(i, cv_ps))
    end associate
  end subroutine make_curve
end module iem_nonlinear_springs
