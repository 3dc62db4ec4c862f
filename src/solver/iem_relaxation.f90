!> Quasi-static analysis by dynamic relaxation (docs/model.md, "Static analysis"): each load
!> step relaxes the lattice to equilibrium under the loads and prescribed displacements of a
!> pseudo-time t_k, by explicit fictitious dynamics (central differences) with kinetic damping
!> or adaptive viscous damping, until the relative residual of the free dofs is below the
!> tolerance.
!>
!> Forces come from model%rate (with zero velocities, so no damping forces), after a halo
!> exchange of the state before every evaluation. Global sums: kinetic damping reduces one
!> number (the kinetic energy) every iteration, and every relax_check_interval iterations the
!> residual norms ride in the same MPI_Allreduce; viscous damping reduces only at those checks.
!> Nothing is allocated inside the iteration loop. Spring history (nonlinear springs) is never
!> committed by an iteration: the caller commits once per converged load step.
module iem_relaxation
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_IN_PLACE, MPI_SUM
  use iem_kinds, only: wp, mpi_wp
  use iem_config, only: static_config_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t
  use iem_time_function, only: tf_value
  use iem_stable_dt, only: cell_stiffness, cell_omega_max
  use iem_alloc_guard, only: alloc_guard_t
  implicit none
  private
  public :: relaxation_t, relax_result_t, relax_check_interval, relax_step_safety

  !> Iterations between residual checks (and viscous damping updates).
  integer, parameter :: relax_check_interval = 10
  !> Fictitious step as a fraction of the central-difference limit dt*omega_max = 2.
  real(wp), parameter :: relax_step_safety = 0.95_wp
  integer, parameter :: method_kinetic = 1, method_viscous = 2

  !> Outcome of one load step (global values, the same on every rank, except work).
  type :: relax_result_t
    !> Relaxation iterations (position updates) done.
    integer :: iterations = 0
    !> Kinetic energy peaks (velocity resets) of kinetic damping.
    integer :: resets = 0
    !> Relative residual reached: ||f_ext - f_int|| over free dofs / reference force.
    real(wp) :: residual = 0.0_wp
    !> Load factor at the step's pseudo-time (see relaxation_load_factor).
    real(wp) :: load_factor = 0.0_wp
    !> This rank's share of the work of the loads and support reactions over the step
    !> (trapezoidal rule; the caller sums over ranks, as for the dynamic run's work).
    real(wp) :: work = 0.0_wp
    logical :: converged = .false.
    !> False when the iteration produced non-finite values (diverged).
    logical :: finite = .true.
  end type relax_result_t

  !> Settings, fictitious masses and preallocated work arrays of the relaxation on one rank.
  type :: relaxation_t
    type(MPI_Comm) :: comm
    integer :: method = method_kinetic
    integer :: max_iterations = 0
    real(wp) :: tolerance = 0.0_wp
    !> Length of the load path (t_end): the load factor of a run without loads is t/path.
    real(wp) :: path_length = 1.0_wp
    !> Fictitious step (s) with mass = 'lumped'; 1 with mass = 'gershgorin'.
    real(wp) :: dt = 1.0_wp
    !> Highest frequency bound (rad/s) of the lumped-mass lattice (for the log).
    real(wp) :: omega_max = 0.0_wp
    !> Free dofs mask of the owned nodes: 1 free, 0 prescribed.
    real(wp), allocatable :: free_dof(:, :)
    !> Position update per unit acceleration, c = dt^2 m / m_f on free dofs (0 prescribed).
    real(wp), allocatable :: c(:, :)
    !> Fictitious mass over dt^2 of the free dofs (0 prescribed): kinetic energy weights.
    real(wp), allocatable :: mk(:, :)
    !> Position increment of the current iteration (dt times the fictitious velocity).
    real(wp), allocatable :: w(:, :)
    real(wp), allocatable :: acc(:, :)
    !> Converged displacement of the previous step, and that step's increment.
    real(wp), allocatable :: u_conv(:, :), du_conv(:, :)
    !> Prescribed displacement increments of this step and of the previous one.
    real(wp), allocatable :: du_p(:, :), du_p_prev(:, :)
    !> First iterate of the step and its accelerations (viscous damping's Rayleigh quotient).
    real(wp), allocatable :: u0(:, :), acc0(:, :)
    !> Work state (4, n_local) for prescribed velocities and the work evaluations.
    real(wp), allocatable :: yw(:, :)
    !> Per load: f_load . f_ref over free dofs (global), f_ref = all loads at full scale.
    real(wp), allocatable :: load_weight(:)
    real(wp) :: load_weight_sum = 0.0_wp
    !> Reference force: the largest force that has driven the path so far (N).
    real(wp) :: f_ref = 0.0_wp
    !> Viscous damping coefficient times dt (adaptive).
    real(wp) :: cdt = 0.0_wp
    !> Load level of the last converged step and its increment over that step.
    real(wp) :: level_conv = 0.0_wp, dlevel_conv = 0.0_wp
    logical :: have_step = .false.
  contains
    procedure :: init => relaxation_init
    procedure :: step => relaxation_step
    procedure :: load_factor => relaxation_load_factor
    procedure :: free => relaxation_free
  end type relaxation_t

contains

  !> Set up the relaxation for the model on this rank's lattice; collective over comm.
  !> path_length: the pseudo-time of the whole load path (t_end).
  subroutine relaxation_init(this, model, lat, comm, settings, path_length, guard)
    class(relaxation_t), intent(inout) :: this
    type(model_t), intent(in) :: model
    type(local_lattice_t), intent(in) :: lat
    type(MPI_Comm), intent(in) :: comm
    type(static_config_t), intent(in) :: settings
    real(wp), intent(in) :: path_length
    !> A failed allocation is handed to guard (collective all the same); without guard it
    !> stops the program.
    type(alloc_guard_t), intent(inout), optional :: guard
    type(alloc_guard_t) :: g
    integer :: ierr
    real(wp) :: kc(8, 8), m_corner
    real(wp), allocatable :: rowsum(:, :, :)
    real(wp), allocatable :: fref(:, :)
    integer :: l, q, comp, corner, n, ld, mt, c

    call this%free()
    n = lat%n_owned
    this%comm = comm
    this%method = merge(method_viscous, method_kinetic, settings%method == 'viscous')
    this%max_iterations = settings%max_iterations
    this%tolerance = settings%tolerance
    this%path_length = path_length
    allocate(this%free_dof(2, n), this%c(2, n), this%mk(2, n), this%w(2, n), this%acc(2, n), &
             this%u_conv(2, n), this%du_conv(2, n), this%du_p(2, n), this%du_p_prev(2, n), &
             this%u0(2, n), this%acc0(2, n), this%yw(4, lat%n_local), fref(2, n), stat=ierr)
    call g%note(ierr, 'the relaxation work arrays of the rank', &
                192.0_wp*n + 32.0_wp*lat%n_local)
    allocate(this%load_weight(size(model%load_tf)))
    this%load_weight = 0.0_wp
    if (g%failed) then
      ! the load weights are summed over the ranks: take part with zeros, then give up
      if (size(this%load_weight) > 0) call MPI_Allreduce(MPI_IN_PLACE, this%load_weight, &
        size(this%load_weight), mpi_wp(), MPI_SUM, comm)
      call g%pass(guard)
      return
    end if
    this%free_dof = 1.0_wp
    do q = 1, size(model%bc_node)
      this%free_dof(model%bc_comp(q), model%bc_node(q)) = 0.0_wp
    end do
    this%w = 0.0_wp
    this%acc = 0.0_wp
    this%u_conv = 0.0_wp
    this%du_conv = 0.0_wp
    this%du_p = 0.0_wp
    this%du_p_prev = 0.0_wp
    this%u0 = 0.0_wp
    this%acc0 = 0.0_wp
    this%yw = 0.0_wp

    ! Fictitious masses: mk = (a stiffness bound of the dof) / (2 * safety)^2, so that the
    ! central-difference step dt = 1 in the scaled system is stable, dt*omega_max <= 2*safety.
    this%omega_max = 0.0_wp
    do mt = 1, size(model%ks)
      m_corner = 0.25_wp*model%densities(mt)*model%grid%lx*model%grid%ly*model%grid%thickness
      this%omega_max = max(this%omega_max, cell_omega_max(model%ks(mt), m_corner))
    end do
    if (settings%mass == 'gershgorin') then
      ! per dof: Gershgorin row sum of the stiffness, summed cell by cell in ascending cell
      ! order (an upper bound of the assembled row sum); dt = 1 s of fictitious time
      allocate(rowsum(2, 4, size(model%ks)))
      do mt = 1, size(model%ks)
        kc = cell_stiffness(model%ks(mt))
        do corner = 1, 4
          do comp = 1, 2
            rowsum(comp, corner, mt) = sum(abs(kc(2*(corner - 1) + comp, :)))
          end do
        end do
      end do
      this%dt = 1.0_wp
      this%mk(:, 1:n) = 0.0_wp
      do c = 1, lat%n_cells
        do q = 1, 4
          l = lat%cell_nodes(q, c)
          if (l <= n) this%mk(:, l) = this%mk(:, l) + rowsum(:, q, lat%mat(c))
        end do
      end do
      do l = 1, n
        this%mk(:, l) = this%mk(:, l)/(2.0_wp*relax_step_safety)**2
      end do
    else
      ! the model's lumped masses with the step from the cell-level bound of omega_max
      this%dt = 2.0_wp*relax_step_safety/this%omega_max
      do l = 1, n
        this%mk(:, l) = model%mass(l)/this%dt**2
      end do
    end if
    do l = 1, n
      this%mk(:, l) = this%mk(:, l)*this%free_dof(:, l)
      this%c(:, l) = 0.0_wp
      where (this%free_dof(:, l) > 0.0_wp) this%c(:, l) = model%mass(l)/this%mk(:, l)
    end do

    ! Load level: the projection of the loads at time t on all loads at full scale.
    fref = 0.0_wp
    do q = 1, size(model%load_node)
      l = model%load_node(q)
      fref(:, l) = fref(:, l) + model%load_force(:, q)*this%free_dof(:, l)
    end do
    this%load_weight = 0.0_wp
    do q = 1, size(model%load_node)
      l = model%load_node(q)
      ld = model%load_id(q)
      this%load_weight(ld) = this%load_weight(ld) + &
                             dot_product(model%load_force(:, q)*this%free_dof(:, l), fref(:, l))
    end do
    if (size(this%load_weight) > 0) then
      call MPI_Allreduce(MPI_IN_PLACE, this%load_weight, size(this%load_weight), mpi_wp(), &
                         MPI_SUM, comm)
    end if
    this%load_weight_sum = sum(this%load_weight)
    this%f_ref = 0.0_wp
    this%cdt = 0.0_wp
    this%level_conv = 0.0_wp
    this%dlevel_conv = 0.0_wp
    this%have_step = .false.
  end subroutine relaxation_init

  !> Load factor at pseudo-time t: the loads on free dofs projected on all loads at full
  !> scale (the time function's value when one function scales every load); t/path_length in
  !> a run without loads.
  real(wp) function relaxation_load_factor(this, model, t) result(lf)
    class(relaxation_t), intent(in) :: this
    type(model_t), intent(in) :: model
    real(wp), intent(in) :: t
    if (this%load_weight_sum > 0.0_wp) then
      lf = load_level(this, model, t)
    else
      lf = t/this%path_length
    end if
  end function relaxation_load_factor

  !> Load level (0 without loads); no communication.
  real(wp) function load_level(this, model, t) result(level)
    type(relaxation_t), intent(in) :: this
    type(model_t), intent(in) :: model
    real(wp), intent(in) :: t
    integer :: ld
    level = 0.0_wp
    if (.not. this%load_weight_sum > 0.0_wp) return
    do ld = 1, size(this%load_weight)
      level = level + this%load_weight(ld)*tf_value(model%load_tf(ld), t)
    end do
    level = level/this%load_weight_sum
  end function load_level

  !> One load step: from the converged state of pseudo-time t_prev held in y(4, n_local),
  !> relax to equilibrium at pseudo-time t; collective. On return y(1:2, :) holds the
  !> displacements (halo included), y(3:4, :) = 0, and model's last evaluation is at that
  !> state. The first call (t_prev = t = 0) finds the equilibrium at t = 0.
  subroutine relaxation_step(this, model, lat, halo, y, t_prev, t, res)
    class(relaxation_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    real(wp), intent(inout), contiguous :: y(:, :)
    real(wp), intent(in) :: t_prev, t
    type(relax_result_t), intent(out) :: res
    real(wp) :: sums(5), level, s, p_ext, p_damp, f_half, ke, ke_old, rel, a1, a2, q
    integer :: l, n, it, j
    logical :: need_eval, check, half

    n = lat%n_owned
    ! prescribed displacement increments: dt_k times the prescribed velocity at the middle of
    ! the step (exact for velocities that are piecewise linear between step boundaries)
    this%yw(3:4, :) = 0.0_wp
    call model%prescribe(this%yw, 0.5_wp*(t_prev + t))
    do l = 1, n
      this%u_conv(:, l) = y(1:2, l)
      this%du_p(:, l) = (t - t_prev)*this%yw(3:4, l)*(1.0_wp - this%free_dof(:, l))
      y(1:2, l) = y(1:2, l) + this%du_p(:, l)
    end do
    y(3:4, :) = 0.0_wp

    ! Out-of-balance force before any prediction: with the loads on free dofs, the reference
    ! force of the residual (a run driven by prescribed displacements alone has no loads).
    call halo%exchange(y)
    call model%rate(lat, y, t, this%acc, p_ext, p_damp)
    sums = 0.0_wp
    do j = 1, size(model%ext_node)
      l = model%ext_node(j)
      sums(1) = sums(1) + sum((model%fext(:, j)*this%free_dof(:, l))**2)
    end do
    do l = 1, n
      sums(2) = sums(2) + sum((this%acc(:, l)*model%mass(l)*this%free_dof(:, l))**2)
      sums(3) = sums(3) + dot_product(this%du_p(:, l), this%du_p_prev(:, l))
      sums(4) = sums(4) + sum(this%du_p_prev(:, l)**2)
      sums(5) = sums(5) + sum(this%du_p(:, l)**2)
    end do
    call MPI_Allreduce(MPI_IN_PLACE, sums, 5, mpi_wp(), MPI_SUM, this%comm)
    res%load_factor = this%load_factor(model, t)
    res%iterations = 0
    res%resets = 0
    res%residual = 0.0_wp
    res%work = 0.0_wp
    res%converged = .true.
    res%finite = .true.
    level = load_level(this, model, t)
    if (this%f_ref == 0.0_wp .and. sums(1) == 0.0_wp .and. sums(5) == 0.0_wp) then
      ! Nothing has loaded the body yet: the undeformed state is the equilibrium (the
      ! out-of-balance force there is round-off of the force kernel, not a residual).
      this%du_conv = 0.0_wp
      this%du_p_prev = 0.0_wp
      this%level_conv = level
      this%dlevel_conv = 0.0_wp
      this%have_step = .true.
      return
    end if
    this%f_ref = max(this%f_ref, sqrt(sums(1)), sqrt(sums(2)))

    ! Predictor: the previous step's increment of the free dofs, scaled by the ratio of the
    ! load level increments (or, when the loads did not change over the previous step, of the
    ! prescribed displacement increments): exact for a linear response to proportional
    ! loading.
    s = 0.0_wp
    if (this%have_step) then
      if (this%dlevel_conv /= 0.0_wp) then
        s = (level - this%level_conv)/this%dlevel_conv
      else if (sums(4) > 0.0_wp) then
        s = sums(3)/sums(4)
      end if
    end if
    need_eval = .false.
    if (s /= 0.0_wp) then
      do l = 1, n
        y(1:2, l) = y(1:2, l) + s*this%du_conv(:, l)*this%free_dof(:, l)
      end do
      need_eval = .true.
    end if

    ! Relaxation: central differences in the scaled system (unit step), w = position update.
    res%converged = .false.
    this%w = 0.0_wp
    ke = 0.0_wp
    ke_old = 0.0_wp
    half = .true.
    do l = 1, n
      this%u0(:, l) = y(1:2, l)
    end do
    it = 0
    do
      if (need_eval) then
        call halo%exchange(y)
        call model%rate(lat, y, t, this%acc, p_ext, p_damp)
      end if
      need_eval = .true.
      if (it == 0) this%acc0 = this%acc
      check = mod(it, relax_check_interval) == 0 .or. it >= this%max_iterations
      ! velocity update; a start from rest takes half a step
      f_half = merge(0.5_wp, 1.0_wp, half)
      if (this%method == method_kinetic) then
        ke = 0.0_wp
        do l = 1, n
          this%w(:, l) = this%w(:, l) + f_half*this%c(:, l)*this%acc(:, l)
          ke = ke + sum(this%mk(:, l)*this%w(:, l)**2)
        end do
      else
        a1 = (2.0_wp - this%cdt)/(2.0_wp + this%cdt)
        a2 = 2.0_wp/(2.0_wp + this%cdt)
        if (half) then
          a1 = 0.0_wp
          a2 = 0.5_wp
        end if
        do l = 1, n
          this%w(:, l) = a1*this%w(:, l) + a2*this%c(:, l)*this%acc(:, l)
        end do
      end if
      if (check) then
        sums = 0.0_wp
        do l = 1, n
          sums(1) = sums(1) + sum((this%acc(:, l)*model%mass(l)*this%free_dof(:, l))**2)
        end do
        if (this%method == method_kinetic) then
          sums(2) = ke
        else
          ! Rayleigh quotient of the correction so far: (du . dr) / (du . M_f du)
          do l = 1, n
            sums(2) = sums(2) + model%mass(l)*dot_product(y(1:2, l) - this%u0(:, l), &
                      (this%acc0(:, l) - this%acc(:, l))*this%free_dof(:, l))
            sums(3) = sums(3) + sum(this%mk(:, l)*(y(1:2, l) - this%u0(:, l))**2)
          end do
        end if
        call MPI_Allreduce(MPI_IN_PLACE, sums, 3, mpi_wp(), MPI_SUM, this%comm)
        if (.not. all(ieee_is_finite(sums(1:3)))) then
          res%finite = .false.
          res%residual = huge(1.0_wp)
          res%iterations = it
          return
        end if
        if (this%f_ref > 0.0_wp) then
          rel = sqrt(sums(1))/this%f_ref
        else
          rel = merge(0.0_wp, huge(1.0_wp), sums(1) == 0.0_wp)
        end if
        res%residual = rel
        res%iterations = it
        if (rel <= this%tolerance) then
          res%converged = .true.
          exit
        end if
        if (it >= this%max_iterations) exit
        if (this%method == method_kinetic) then
          ke = sums(2)
        else if (sums(3) > 0.0_wp) then
          q = max(sums(2)/sums(3), 0.0_wp)
          this%cdt = min(2.0_wp*sqrt(q), 4.0_wp)
        end if
      else if (this%method == method_kinetic) then
        call MPI_Allreduce(MPI_IN_PLACE, ke, 1, mpi_wp(), MPI_SUM, this%comm)
      end if
      if (this%method == method_kinetic .and. ke < ke_old) then
        ! kinetic energy peak, about half a step back: move there (u - w_old/2) and restart
        ! from rest; w_old is the update before this iteration's velocity change
        do l = 1, n
          y(1:2, l) = y(1:2, l) - 0.5_wp*(this%w(:, l) - f_half*this%c(:, l)*this%acc(:, l))
        end do
        this%w = 0.0_wp
        ke_old = 0.0_wp
        half = .true.
        res%resets = res%resets + 1
      else
        do l = 1, n
          y(1:2, l) = y(1:2, l) + this%w(:, l)
        end do
        ke_old = ke
        half = .false.
      end if
      it = it + 1
    end do
    if (.not. res%converged) return

    ! Work of loads and support reactions over the step, trapezoidal in the displacement
    ! increment: loads on free dofs, internal forces (reactions) on prescribed dofs. The
    ! first step starts from the unloaded reference (zero force).
    do l = 1, n
      this%du_conv(:, l) = y(1:2, l) - this%u_conv(:, l)
    end do
    sums = 0.0_wp
    if (this%have_step) then
      this%yw(1:2, 1:n) = this%u_conv
      this%yw(3:4, 1:n) = this%du_conv
      call halo%exchange(this%yw)
      call model%rate(lat, this%yw, t_prev, this%acc, p_ext, p_damp)
      sums(1) = p_ext - reaction_inertia(model, this%free_dof, this%acc, this%yw, n)
    end if
    y(3:4, 1:n) = this%du_conv
    call halo%exchange(y)
    ! the converged state is accepted: nonlinear springs commit their history to it (the
    ! relaxation iterations above never do)
    call model%rate(lat, y, t, this%acc, p_ext, p_damp, commit=.true.)
    sums(1) = sums(1) + p_ext - reaction_inertia(model, this%free_dof, this%acc, y, n)
    res%work = 0.5_wp*sums(1)
    y(3:4, :) = 0.0_wp

    this%du_p_prev = this%du_p
    if (this%have_step) this%dlevel_conv = level - this%level_conv
    this%level_conv = level
    this%have_step = .true.
  end subroutine relaxation_step

  !> The part of model%rate's external power that is the prescribed dofs' imposed
  !> acceleration (mass times acceleration times velocity), to be removed in a static run.
  pure real(wp) function reaction_inertia(model, free, acc, y, n) result(p)
    type(model_t), intent(in) :: model
    real(wp), intent(in) :: free(:, :), acc(:, :), y(:, :)
    integer, intent(in) :: n
    integer :: l
    p = 0.0_wp
    do l = 1, n
      p = p + model%mass(l)*sum((1.0_wp - free(:, l))*acc(:, l)*y(3:4, l))
    end do
  end function reaction_inertia

  !> Release the arrays.
  subroutine relaxation_free(this)
    class(relaxation_t), intent(inout) :: this
    if (allocated(this%c)) deallocate(this%c, this%mk, this%w, this%acc, this%u_conv, &
      this%du_conv, this%du_p, this%du_p_prev, this%u0, this%acc0, this%yw)
    if (allocated(this%load_weight)) deallocate(this%load_weight)
    if (allocated(this%free_dof)) deallocate(this%free_dof)
    this%have_step = .false.
  end subroutine relaxation_free
end module iem_relaxation
