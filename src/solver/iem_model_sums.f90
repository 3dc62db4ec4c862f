!> The model's exact sums (model_add_work, model_collect_work, model_damping_work,
!> model_energy_sums, model_reaction_sums, documented at their interfaces in iem_model.f90):
!> the work and dissipation of a step's evaluations (the damping's folded a node and a cell
!> at a time, then collected), and a rank's energies and reactions for the history's exact
!> global sums; the damping's arrays and a run of nodes' terms before its pass.
submodule (iem_model) iem_model_sums
  use iem_node_pass, only: mass_damping_powers
  implicit none

contains

  !> Documented at its interface in iem_model.f90.
  module procedure model_add_work
    integer :: c
    call this%w_ext_acc%add_scaled(this%pe_slot, wdt)
    call this%w_ext_acc%add_scaled(this%pr_bc, wdt)
    call model_damping_arrays(this, lat)
    if (this%beta > 0.0_wp) then
      ! every local cell's (the counted ones are collected)
      do c = 1, lat%n_cells
        this%wd_cell(c) = this%wd_cell(c) + wdt*this%pw_cell(c)
      end do
    end if
    if (present(folded)) then
      if (folded) return
    end if
    if (this%alpha > 0.0_wp) call model_fold_work(this, 1, lat%n_owned, wdt)
  end procedure model_add_work

  !> Documented at its interface in iem_model.f90.
  module procedure model_collect_work
    call add_folds(this, lat, this%w_damp_acc)
    if (allocated(this%wd_node)) this%wd_node = 0.0_wp
    if (allocated(this%wd_cell)) this%wd_cell = 0.0_wp
  end procedure model_collect_work

  !> Documented at its interface in iem_model.f90.
  module procedure model_damping_work
    acc = this%w_damp_acc
    call add_folds(this, lat, acc)
  end procedure model_damping_work

  !> The owned nodes' wd_node and the counted cells' wd_cell added to acc exactly.
  subroutine add_folds(this, lat, acc)
    class(model_t), intent(in) :: this
    type(local_lattice_t), intent(in) :: lat
    type(exact_sum_t), intent(inout) :: acc
    if (this%alpha > 0.0_wp .and. size(this%wd_node) > 0) &
      call acc%add(this%wd_node(1:min(lat%n_owned, size(this%wd_node))))
    if (this%beta <= 0.0_wp .or. size(this%wd_cell) < lat%n_cells) return
    call add_counted(lat, this%wd_cell, 1.0_wp, acc)
  end subroutine add_folds

  !> w times the values v(c) of the counted cells (first corner owned) added to acc, a chunk
  !> at a time (w = 1: the values themselves).
  subroutine add_counted(lat, v, w, acc)
    type(local_lattice_t), intent(in) :: lat
    real(wp), intent(in) :: v(:), w
    type(exact_sum_t), intent(inout) :: acc
    integer :: c, j, m, c0, k, fc(max_chunk)
    real(wp) :: counted(max_chunk)
    do j = 1, lat%cells%n_chunks()
      call lat%first_corners(j, fc, m)
      c0 = lat%cells%chunks(1, j) - 1
      k = 0
      do c = 1, m
        if (fc(c) > lat%n_owned) cycle
        k = k + 1
        counted(k) = w*v(c0 + c)
      end do
      call acc%add(counted(1:k))
    end do
  end subroutine add_counted

  !> Documented at its interface in iem_model.f90.
  module procedure model_fold_work
    integer :: l
    do l = lo, hi
      this%wd_node(l) = this%wd_node(l) + wdt*this%pw_node(l)
    end do
  end procedure model_fold_work

  !> Documented at its interface in iem_model.f90.
  module procedure model_damping_arrays
    if (this%beta > 0.0_wp .and. size(this%pw_cell) < lat%n_cells) &
      call grow(this%pw_cell, lat%n_cells)
    if (this%beta > 0.0_wp .and. size(this%wd_cell) < lat%n_cells) &
      call grow(this%wd_cell, lat%n_cells)
    if (this%alpha > 0.0_wp .and. size(this%pw_node) < lat%n_owned) &
      call grow(this%pw_node, lat%n_owned)
    if (this%alpha > 0.0_wp .and. size(this%wd_node) < lat%n_owned) &
      call grow(this%wd_node, lat%n_owned)
  contains

    !> a resized to n values, the old ones kept, the new ones 0.
    subroutine grow(a, n)
      real(wp), allocatable, intent(inout) :: a(:)
      integer, intent(in) :: n
      real(wp), allocatable :: b(:)
      allocate(b(n), source=0.0_wp)
      b(1:size(a)) = a
      call move_alloc(b, a)
    end subroutine grow
  end procedure model_damping_arrays

  !> Documented at its interface in iem_model.f90.
  module procedure model_energy_sums
    integer, parameter :: nb = 256
    integer :: l, l0, n
    real(wp) :: buf(nb)
    ! (a buffer of terms at a time: the exact sum's array form is the faster)
    do l0 = 1, lat%n_owned, nb
      n = min(nb, lat%n_owned - l0 + 1)
      do l = 1, n
        buf(l) = 0.5_wp*this%mass(l0 + l - 1)*(y(3, l0 + l - 1)**2 + y(4, l0 + l - 1)**2)
      end do
      call sums(1)%add(buf(1:n))
    end do
    if (present(acc) .and. present(h)) sums(6) = this%kick_term(lat, acc, h)
    sums(2) = this%en_sum
    sums(3) = this%w_ext_acc
    sums(4) = this%damping_work(lat)
    if (this%fracture) call add_counted(lat, this%fr%diss, 1.0_wp, sums(5))
  end procedure model_energy_sums

  !> Documented at its interface in iem_model.f90.
  module procedure model_kick_term
    integer, parameter :: nb = 256
    integer :: l, l0, n
    real(wp) :: buf(nb)
    logical :: mass_damped
    if (h <= 0.0_wp) return
    ! a node's terms as one (the same on any rank), a buffer of them at a time
    mass_damped = this%alpha > 0.0_wp .and. size(this%pw_node) >= lat%n_owned
    do l0 = 1, lat%n_owned, nb
      n = min(nb, lat%n_owned - l0 + 1)
      if (mass_damped) then
        do l = 1, n
          buf(l) = 0.5_wp*h*(h*this%mass(l0 + l - 1)*(a(1, l0 + l - 1)**2 + &
                   a(2, l0 + l - 1)**2) + this%pw_node(l0 + l - 1))
        end do
      else
        do l = 1, n
          buf(l) = 0.5_wp*h*h*this%mass(l0 + l - 1)*(a(1, l0 + l - 1)**2 + a(2, l0 + l - 1)**2)
        end do
      end if
      call acc%add(buf(1:n))
    end do
    if (this%beta > 0.0_wp .and. this%omega_cap <= 0.0_wp .and. &
        size(this%pw_cell) >= lat%n_cells) call add_counted(lat, this%pw_cell, 0.5_wp*h, acc)
  end procedure model_kick_term

  !> Documented at its interface in iem_model.f90.
  module procedure model_reaction_sums
    integer :: n, l, comp, b
    real(wp) :: r
    do n = 1, size(this%bc_node)
      l = this%bc_node(n)
      comp = this%bc_comp(n)
      b = this%bc_id(n)
      if (t >= this%bc_release(b)) cycle
      r = this%r_bc(n)
      if (inertia) r = this%mass(l)*(this%bc_velocity(comp, b)*tf_rate(this%bc_tf(b), t) + &
                       this%alpha*y(2 + comp, l)) + r
      call sums(2*(series(b) - 1) + comp)%add(r)
    end do
  end procedure model_reaction_sums
  !> Documented at its interface in iem_model.f90.
  module procedure model_set_loads
    real(wp) :: r, ms(size(this%load_tf))
    integer :: ld, n, s
    logical :: changed
    changed = .false.
    do ld = 1, size(this%load_tf)
      r = tf_value(this%load_tf(ld), t)
      if (r /= this%load_scale(ld)) changed = .true.
      this%load_scale(ld) = r
    end do
    if (changed) then
      this%fext = 0.0_wp
      do n = 1, size(this%load_node)
        s = this%load_slot(n)
        this%fext(:, s) = this%fext(:, s) + this%load_force(:, n)*this%load_scale(this%load_id(n))
      end do
    end if
    ! velocity Verlet's step: the loads' mean over it, for their powers, where it differs
    this%fmean_on = .false.
    if (this%mean_dt <= 0.0_wp) return
    do ld = 1, size(this%load_tf)
      ms(ld) = 0.5_wp*(tf_value(this%load_tf(ld), t - this%mean_dt) + this%load_scale(ld))
      if (ms(ld) /= this%load_scale(ld)) this%fmean_on = .true.
    end do
    if (.not. this%fmean_on) return
    if (allocated(this%fmean)) then
      if (size(this%fmean, 2) /= size(this%fext, 2)) deallocate(this%fmean)
    end if
    if (.not. allocated(this%fmean)) allocate(this%fmean(2, size(this%fext, 2)))
    this%fmean = 0.0_wp
    do n = 1, size(this%load_node)
      s = this%load_slot(n)
      this%fmean(:, s) = this%fmean(:, s) + this%load_force(:, n)*ms(this%load_id(n))
    end do
  end procedure model_set_loads

  !> Documented at its interface in iem_model.f90.
  module procedure model_external_power
    integer :: s, n
    p = 0.0_wp
    do s = 1, size(this%ext_node)
      p = p + this%pe_slot(s)
    end do
    do n = 1, size(this%bc_node)
      if (this%pr_on(n)) p = p + this%pr_bc(n)
    end do
  end procedure model_external_power
  !> Documented at its interface in iem_model.f90.
  module procedure model_run_terms
    real(wp) :: none
    integer :: q, l
    do while (jb <= size(this%bc_by_node))
      if (this%bc_node(this%bc_by_node(jb)) >= lo) exit
      jb = jb + 1
    end do
    j0 = jb
    do while (jb <= size(this%bc_by_node))
      q = this%bc_by_node(jb)
      if (this%bc_node(q) > hi) exit
      call this%reaction_terms(q, fs, y, t, this%fext, keep, this%pr_bc(q), this%pr_on(q))
      jb = jb + 1
    end do
    do while (js <= size(this%ext_node))
      if (this%ext_node(js) >= lo) exit
      js = js + 1
    end do
    do while (js <= size(this%ext_node))
      l = this%ext_node(js)
      if (l > hi) exit
      this%pe_slot(js) = this%slot_power(js, y)
      fs(:, l) = fs(:, l) - this%fext(:, js)
      js = js + 1
    end do
    none = 0.0_wp
    if (this%alpha <= 0.0_wp) return
    if (present(fold)) then
      call mass_damping_powers(hi - lo + 1, this%alpha, this%mass(lo:hi), y(:, lo:hi), &
                               this%pw_node(lo:hi), none, this%wd_node(lo:hi), fold)
    else
      call mass_damping_powers(hi - lo + 1, this%alpha, this%mass(lo:hi), y(:, lo:hi), &
                               this%pw_node(lo:hi), none)
    end if
  end procedure model_run_terms
end submodule iem_model_sums
